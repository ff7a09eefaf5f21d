"""Atomic writes: temporary files renamed into place, output folders, manifests.

Every file the toolbox writes goes through :func:`atomic_write` (a temporary file
``.hubbeam-tmp-<pid>-<random>-<name>`` in the target folder, then a rename), so an
interrupted write never leaves a half-written file; temporaries are removed on failure, on
SIGTERM/SIGINT and at exit, and those of killed processes by the next writer in the folder.
Final files get the permissions the umask allows. :func:`check_writable` tests an output
path before any work. Multi-file outputs go through :func:`write_folder`, which marks a
finished folder with a manifest written last (:func:`read_manifest` checks it).
Reading inputs is :mod:`hubbeam_ctrl.core.reading`, JSON text :mod:`hubbeam_ctrl.core.jsonio`,
the NPZ layout :mod:`hubbeam_ctrl.core.npz`.
"""

from __future__ import annotations

import atexit
import hashlib
import json
import os
import secrets
import shutil
import signal
import threading
import time
from pathlib import Path

from hubbeam_ctrl.core.errors import ParameterError, write_error

__all__ = ["atomic_write", "atomic_write_text", "check_writable", "output_folder", "write_folder",
           "read_manifest", "remove_stale_temporaries", "remove_temporaries", "TEMP_PREFIX", "MANIFEST"]


#: Prefix of every temporary file or folder the toolbox writes (next to the final one).
TEMP_PREFIX = ".hubbeam-tmp-"

#: Name of the manifest written last into a multi-file output folder.
MANIFEST = "MANIFEST.json"

#: Temporary files and folders of this process not yet renamed into place.
_LIVE: set = set()
_HANDLED_SIGNALS = (signal.SIGTERM, signal.SIGINT)
_PREVIOUS_HANDLERS: dict = {}

#: Longest file name the system takes [bytes] (the temporary names add ``_TEMP_EXTRA``).
_NAME_MAX = 255
_TEMP_EXTRA = len(TEMP_PREFIX) + 24

#: Temporary entries older than this belong to a finished writer, whatever their pid says [s].
STALE_AFTER_S = 24 * 3600.0


def _umask() -> int:
    """The process's umask, read without changing it where the system allows."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _temp_name(final_name: str) -> str:
    """``.hubbeam-tmp-<pid>-<random>-<final name>`` (the final suffix kept for writers that
    choose the format by extension)."""
    return f"{TEMP_PREFIX}{os.getpid()}-{secrets.token_hex(4)}-{final_name}"


def _remove_entry(path) -> None:
    try:
        if os.path.isdir(path) and not os.path.islink(path):
            shutil.rmtree(path, ignore_errors=True)
        elif os.path.lexists(path):
            os.unlink(path)
    except OSError:
        pass
    _LIVE.discard(str(path))


def remove_temporaries() -> None:
    """Remove this process's unfinished temporary files and folders (at exit, on SIGTERM/SIGINT)."""
    for path in list(_LIVE):
        _remove_entry(path)


def _on_signal(signum, frame):
    remove_temporaries()
    previous = _PREVIOUS_HANDLERS.get(signum, signal.SIG_DFL)
    if callable(previous):
        previous(signum, frame)
        return
    signal.signal(signum, signal.SIG_DFL if previous is None else previous)
    os.kill(os.getpid(), signum)


def _install_cleanup() -> None:
    """Remove temporaries on SIGTERM/SIGINT and at exit (once; main thread only)."""
    if _PREVIOUS_HANDLERS or threading.current_thread() is not threading.main_thread():
        return
    for sig in _HANDLED_SIGNALS:
        try:
            _PREVIOUS_HANDLERS[sig] = signal.getsignal(sig)
            signal.signal(sig, _on_signal)
        except (ValueError, OSError):
            pass
    atexit.register(remove_temporaries)


def _stale(name: str, folder: Path) -> bool:
    """True for a temporary entry whose writer has gone (its pid is dead, or it is old)."""
    try:
        pid = int(name[len(TEMP_PREFIX):].split("-", 1)[0])
    except ValueError:
        pid = None
    if pid is not None and pid != os.getpid():
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        except OSError:
            pass
    try:
        return time.time() - os.lstat(folder / name).st_mtime > STALE_AFTER_S
    except OSError:
        return False


def remove_stale_temporaries(folder) -> list:
    """Remove temporary files and folders left in ``folder`` by writers that were killed.

    An entry is stale when its name starts with :data:`TEMP_PREFIX` and the process that
    made it (the pid in its name) no longer exists, or it is older than
    :data:`STALE_AFTER_S`. Every writer calls this for its target folder.

    Parameters
    ----------
    folder : str or Path

    Returns
    -------
    list of str
        The names removed.
    """
    folder = Path(folder)
    try:
        names = [n for n in os.listdir(folder) if n.startswith(TEMP_PREFIX)]
    except OSError:
        return []
    removed = [n for n in names if _stale(n, folder)]
    for name in removed:
        _remove_entry(folder / name)
    return removed


def check_writable(path, option: str = "out") -> Path:
    """Check, before any work, that a file can be written at ``path``.

    Refused: an empty name; a missing parent folder; a folder or another non-regular file
    (a FIFO, a device) at ``path``; a name too long for the system once the temporary
    prefix is added; a folder where a probe file cannot be created (read-only, full,
    ``/proc``).

    Parameters
    ----------
    path : str or Path
        The file to be written (it may exist: it is replaced).
    option : str
        The argument's name as the caller spelled it (starts the message).

    Returns
    -------
    Path
        ``Path(path)``, checked.

    Raises
    ------
    ParameterError
        One line naming ``option`` and the reason.
    """
    if path is None or str(path).strip() == "":
        raise ParameterError(f"{option} must name a file, got {str(path)!r}")
    path = Path(path)
    _check_name_length(path, option)
    folder = path.parent if str(path.parent) else Path(".")
    try:
        if not folder.is_dir():
            raise ParameterError(f"{option}: folder {folder} does not exist")
        if path.is_dir():
            raise ParameterError(f"{option}: {path} is a folder, not a file name")
        if path.exists() and not path.is_file():
            raise ParameterError(f"{option}: {path} exists and is not a regular file")
    except OSError as exc:
        raise ParameterError(f"{option}: cannot use {str(path)[:80]} ({exc.strerror or exc})") from None
    _probe(folder, option)
    return path


def _check_name_length(path: Path, option: str) -> None:
    """Refuse a name that, with the temporary prefix, the system would not take."""
    try:
        parts = [len(os.fsencode(p)) for p in path.parts]
    except UnicodeError:
        raise ParameterError(f"{option}: the name {str(path)[:80]!r} cannot be encoded") from None
    size = parts[-1] if parts else 0
    if size > _NAME_MAX - _TEMP_EXTRA:
        raise ParameterError(f"{option}: file name too long ({size} bytes; at most "
                             f"{_NAME_MAX - _TEMP_EXTRA})")
    if max(parts, default=0) > _NAME_MAX or sum(parts) > 4000:
        raise ParameterError(f"{option}: path too long ({sum(parts)} bytes)")


def _probe(folder: Path, option: str) -> None:
    """Create and remove a temporary file in ``folder``, or raise naming ``option``."""
    probe = folder / _temp_name("probe")
    try:
        fd = os.open(probe, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ParameterError(f"{option}: cannot write to folder {folder} ({exc.strerror or exc})") from None


def atomic_write(path, write, suffix: str | None = None, option: str = "out") -> Path:
    """Write a file atomically.

    The content goes to a temporary file ``.hubbeam-tmp-<pid>-<random>-<name>`` in the target
    folder, which is renamed into place once complete and given the permissions the umask
    allows (``0666 & ~umask``, not the temporary file's 0600). The temporary file is removed
    if the write fails, on SIGTERM or SIGINT and at exit; one left by a killed process is
    removed by the next writer in that folder (:func:`remove_stale_temporaries`).

    Parameters
    ----------
    path : str or Path
        Final file name.
    write : callable
        ``write(tmp_path)`` writes the whole content to the temporary path it is given.
    suffix : str, optional
        Extension the temporary file must end with (some writers insist on one); by default
        the temporary name ends with the final name, so it has the final extension.
    option : str
        The path's name as the caller spelled it (``"out"``, ``"plot"``), starting the messages.

    Returns
    -------
    Path
        The final path.

    Raises
    ------
    ParameterError
        Naming the path (as ``option``) when its folder is missing, it is a folder, or
        the system refuses the write; no file is left behind.
    ResourceError
        When the system runs out of space, quota or the device fails (not bad input).
    Exception
        Whatever else ``write`` raises, unchanged; the temporary file is removed and an
        existing file at ``path`` keeps its old content.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ParameterError(f"{option}: folder {folder} does not exist")
    if path.is_dir():
        raise ParameterError(f"{option}: {path} is a folder, not a file name")
    _check_name_length(path, option)
    _install_cleanup()
    remove_stale_temporaries(folder)
    name = path.name if not suffix or path.name.endswith(suffix) else path.name + suffix
    tmp = str(folder / _temp_name(name))
    _LIVE.add(tmp)
    try:
        os.close(os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
        write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except OSError as exc:
        _remove_entry(tmp)
        raise write_error(exc, f"{option}: cannot write {path}") from None
    except BaseException:
        _remove_entry(tmp)
        raise
    _LIVE.discard(tmp)
    return path


def write_folder(path, write, option: str = "out") -> Path:
    """Write a multi-file output folder so that a reader can tell finished from interrupted.

    ``write(tmp_folder)`` writes every file into a temporary folder next to ``path``; a
    :data:`MANIFEST` listing the files, their sizes and SHA-256 digests is written last.
    A new folder is then renamed into place in one step. Into an existing folder the old
    manifest is removed first, the files are moved in one by one (each atomically) and the
    new manifest comes last, so an interrupted update leaves no manifest (or the old one
    with different digests): :func:`read_manifest` refuses it. Files of the folder that the
    writer does not produce are left alone.

    Parameters
    ----------
    path : str or Path
        The output folder (its parent must exist).
    write : callable
        ``write(folder)`` writes the files (flat, no subfolders) into the folder it is given.
    option : str
        The argument's name as the caller spelled it (starts error messages).

    Returns
    -------
    Path
    """
    path = Path(path)
    if str(path).strip() == "":
        raise ParameterError(f"{option} must name a folder, got ''")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise ParameterError(f"{option}: folder {parent} does not exist")
    if path.exists() and not path.is_dir():
        raise ParameterError(f"{option}: {path} exists and is not a folder")
    _install_cleanup()
    remove_stale_temporaries(parent)
    tmp = parent / _temp_name(path.name)
    _LIVE.add(str(tmp))
    try:
        os.mkdir(tmp)
        write(tmp)
        names = sorted(n for n in os.listdir(tmp) if n != MANIFEST)
        atomic_write_text(tmp / MANIFEST, json.dumps(_manifest(tmp, names), indent=1) + "\n")
        os.chmod(tmp, 0o777 & ~_umask())
        _move_into_place(tmp, path, names)
    except OSError as exc:
        _remove_entry(tmp)
        raise write_error(exc, f"{option}: cannot write {path}") from None
    except BaseException:
        _remove_entry(tmp)
        raise
    _LIVE.discard(str(tmp))
    return path


def _manifest(folder: Path, names: list) -> dict:
    files = {}
    for name in names:
        data = (folder / name).read_bytes()
        files[name] = {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    return {"format": "hubbeam-output", "version": 1, "complete": True, "files": files,
            "written": time.strftime("%Y-%m-%dT%H:%M:%S%z")}


def _move_into_place(tmp: Path, path: Path, names: list) -> None:
    if not path.exists():
        try:
            os.rename(tmp, path)
            return
        except OSError:
            if not path.is_dir():
                raise
    (path / MANIFEST).unlink(missing_ok=True)
    for name in names:
        os.replace(tmp / name, path / name)
    os.replace(tmp / MANIFEST, path / MANIFEST)
    os.rmdir(tmp)


def read_manifest(folder, option: str = "path") -> dict:
    """The manifest of a folder written by :func:`write_folder`, checked against its files.

    Parameters
    ----------
    folder : str or Path
        An output folder of a command (``hubbeam compare --out``, ``identify``, ``codegen``...).
    option : str
        The argument's name as the caller spelled it (starts error messages).

    Returns
    -------
    dict
        ``files`` maps each name to its ``bytes`` and ``sha256``.

    Raises
    ------
    ParameterError
        No manifest (an interrupted or foreign folder), or a file missing or different from
        what the manifest lists (an interrupted update).
    """
    folder = Path(folder)
    try:
        doc = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
        files = doc["files"]
        ok = doc.get("format") == "hubbeam-output" and doc.get("complete") is True and isinstance(files, dict)
    except FileNotFoundError:
        raise ParameterError(f"{option}: {folder} is incomplete (no {MANIFEST}: an interrupted run, "
                             f"or not a hubbeam output folder)") from None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ParameterError(f"{option}: {folder}/{MANIFEST} is unreadable ({type(exc).__name__})") from None
    if not ok:
        raise ParameterError(f"{option}: {folder}/{MANIFEST} is not a hubbeam manifest")
    for name, entry in files.items():
        try:
            data = (folder / name).read_bytes()
        except OSError:
            raise ParameterError(f"{option}: {folder} is incomplete ({name} is missing)") from None
        if len(data) != entry.get("bytes") or hashlib.sha256(data).hexdigest() != entry.get("sha256"):
            raise ParameterError(f"{option}: {folder} is inconsistent ({name} differs from its manifest "
                                 f"entry: an interrupted update)")
    return doc


def atomic_write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (UTF-8).

    Parameters
    ----------
    path : str or Path
        Final file name.
    text : str
        Whole content.

    Returns
    -------
    Path
    """
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def output_folder(out_dir, option: str = "out", create: bool = True) -> Path:
    """An output folder: its parent must exist and it must not be a file; created if missing.

    Parameters
    ----------
    out_dir : str or Path
        The folder.
    option : str
        How the caller spells the argument (starts the messages).
    create : bool
        Create the folder (else only check that it can be).

    Returns
    -------
    Path
        The folder, which exists unless ``create`` is false.

    Raises
    ------
    ParameterError
        One line naming ``option`` when the parent is missing or the path is a file.
    """
    out = Path(out_dir)
    if not out.parent.is_dir():
        raise ParameterError(f"{option}: folder {out.parent} does not exist")
    if out.exists() and not out.is_dir():
        raise ParameterError(f"{option}: {out} exists and is not a folder")
    if create:
        out.mkdir(exist_ok=True)
    return out


#: Largest TOML input read (parameters, study specs, settings) [bytes].
