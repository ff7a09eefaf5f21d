"""File helpers: atomic writes, output folders, and NPZ files of arrays plus JSON metadata.

Every file the toolbox writes goes through :func:`atomic_write` (a temporary file
``.hubbeam-tmp-<pid>-<random>-<name>`` in the target folder, then a rename), so an
interrupted write never leaves a half-written file; temporaries are removed on failure, on
SIGTERM/SIGINT and at exit, and those of killed processes by the next writer in the folder.
Final files get the permissions the umask allows. :func:`check_writable` tests an output
path before any work. Multi-file outputs go through :func:`write_folder`, which marks a
finished folder with a manifest written last (:func:`read_manifest` checks it).
:func:`write_npz` and :func:`read_npz` are the one NPZ layout of the toolbox: named arrays
plus a ``metadata`` entry holding a JSON document; :func:`read_npz` turns every way a file
can be unreadable into a one-line :class:`~hubbeam_ctrl.core.errors.ParameterError`.
"""

from __future__ import annotations

import atexit
import dataclasses
import hashlib
import json
import os
import secrets
import shutil
import signal
import threading
import time
from pathlib import Path

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError, write_error

__all__ = ["read_toml", "path_exists", "MAX_TOML_BYTES", "MAX_NPZ_BYTES",
           "atomic_write", "atomic_write_text", "json_ready", "strict_json", "write_npz", "read_npz",
           "check_regular_file", "check_writable", "output_folder", "write_folder", "read_manifest",
           "remove_stale_temporaries", "remove_temporaries", "TEMP_PREFIX", "MANIFEST"]


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
    option : str
        The argument's name as the caller spelled it (starts the message).

    Returns
    -------
    Path

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
        raise ParameterError(f"{option}: cannot write {path}: {exc.strerror or exc}") from None
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


def _json_default(obj):
    """``json.dumps`` fallback: NumPy scalars and arrays, dataclasses, paths, else ``str``."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return dataclasses.asdict(obj)
    return str(obj)


def _dumps(value) -> str:
    return json.dumps(value, default=_json_default)


def json_ready(value):
    """``value`` as it reads back from JSON: tuples become lists, NumPy scalars plain numbers.

    Storing metadata in this form makes a save/load round trip return equal values.

    Parameters
    ----------
    value : object
        Nested dicts, lists, numbers, strings; NumPy values, dataclasses and paths are
        converted, anything else becomes its ``str``.

    Returns
    -------
    object
    """
    return json.loads(_dumps(value))


def _finite_only(value, flag: str):
    """``value`` with non-finite floats as ``None``; each dict that had some lists their keys
    under ``flag``."""
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.ndarray):
        return _finite_only(value.tolist(), flag)
    if isinstance(value, (list, tuple)):
        return [_finite_only(v, flag) for v in value]
    if isinstance(value, dict):
        out, bad = {}, []
        for k, v in value.items():
            out[k] = _finite_only(v, flag)
            if out[k] is None and isinstance(v, (float, np.floating)):
                bad.append(k)
        if bad:
            out[flag] = bad
        return out
    return value


def strict_json(value, flag: str = "non_finite", **kwargs) -> str:
    """Strict JSON text (``allow_nan=False``): NaN and infinities become ``null``.

    Every object that had such values gets ``flag`` listing their keys, so ``null`` is
    never mistaken for a missing value.

    Parameters
    ----------
    value : object
        Nested dicts, lists, numbers, strings (NumPy values accepted).
    flag : str
        Key of the list of replaced entries.
    **kwargs
        Passed to :func:`json.dumps` (``indent``...).

    Returns
    -------
    str

    Examples
    --------
    >>> strict_json({"peak": float("nan"), "n": 3})
    '{"peak": null, "n": 3, "non_finite": ["peak"]}'
    """
    return json.dumps(_finite_only(value, flag), allow_nan=False, default=_json_default, **kwargs)


def write_npz(path, arrays: dict, metadata: dict) -> Path:
    """Write named arrays and a JSON ``metadata`` entry to an ``.npz`` file, atomically.

    Parameters
    ----------
    path : str or Path
        File name (``.npz``).
    arrays : dict
        Name -> ndarray (not ``metadata``); stored bit for bit.
    metadata : dict
        JSON-serialisable document (see :func:`json_ready`).

    Returns
    -------
    Path
    """
    text = _dumps(metadata)

    def write(tmp):
        with open(tmp, "wb") as fh:
            np.savez(fh, metadata=np.array(text), **arrays)
    return atomic_write(path, write)


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
MAX_TOML_BYTES = 1_000_000


def _short_path(path) -> str:
    """``path`` as shown in a one-line message: at most 120 characters (a name past PATH_MAX is cut
    in the middle, so the message still ends with its reason)."""
    text = str(path)
    return text if len(text) <= 120 else f"{text[:60]}...{text[-40:]}"


def path_exists(path) -> bool:
    """``Path(path).exists()``, False for a name the system refuses (past NAME_MAX or PATH_MAX):
    the reader that follows names the reason.

    Parameters
    ----------
    path : str or Path
    """
    try:
        return Path(path).exists()
    except (OSError, ValueError):
        return False


def read_toml(path, what: str = "file", max_bytes: int = MAX_TOML_BYTES) -> dict:
    """The TOML document at ``path``, or a one-line :class:`ParameterError` naming the file.

    The one reader of every TOML input (``--params``, study specs, ``--settings``). Refused
    without blocking or a traceback: a missing path, a folder, a FIFO or device (never
    opened), an unreadable file, a file over ``max_bytes``, bytes that are not UTF-8,
    invalid or too deeply nested TOML.

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What the file is, as the message starts (``"params file"``, ``"spec: file"``).
    max_bytes : int
        Largest size read [bytes].

    Returns
    -------
    dict
    """
    import tomllib
    if path is None or not isinstance(path, (str, os.PathLike)) or str(path).strip() == "" \
            or "\x00" in str(path):
        raise ParameterError(f"{what} must be named by a path, got {path!r}")
    path = Path(path)
    name = _short_path(path)
    try:
        if not path.exists():
            raise ParameterError(f"{what} {name} does not exist")
        if not path.is_file():
            raise ParameterError(f"{what} {name} is not a regular file")
        if path.stat().st_size > max_bytes:
            raise ParameterError(f"{what} {name} is larger than {max_bytes} bytes")
        with open(path, "rb") as fh:
            data = fh.read(max_bytes + 1)
        if len(data) > max_bytes:
            raise ParameterError(f"{what} {name} is larger than {max_bytes} bytes")
        text = data.decode("utf-8")
    except OSError as exc:
        raise ParameterError(f"{what} {name} cannot be read ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise ParameterError(f"{what} {name} is not UTF-8 text (byte {exc.start})") from None
    if "\x00" in text:
        raise ParameterError(f"{what} {name} is not a text file (NUL byte)")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"{what} {name} is not valid TOML: {' '.join(str(exc).split())[:200]}") from None
    except RecursionError:
        raise ParameterError(f"{what} {name} is nested too deeply") from None


def check_regular_file(path, option: str = "path") -> Path:
    """Return ``Path(path)``; raise unless it names an existing regular file.

    Parameters
    ----------
    path : str or Path
    option : str
        The argument's name as the caller spelled it (starts the error message).

    Returns
    -------
    Path
    """
    path = Path(path)
    try:
        if not path.exists():
            raise ParameterError(f"{option}: file {_short_path(path)} does not exist")
        if not path.is_file():
            raise ParameterError(f"{option}: {_short_path(path)} is not a regular file")
    except OSError as exc:             # a name past NAME_MAX or PATH_MAX
        raise ParameterError(f"{option}: {_short_path(path)} cannot be read ({exc.strerror or exc})") from None
    return path


#: Largest total uncompressed size of the arrays of an ``.npz`` file read [bytes] (the limit
#: is on what is unpacked, not on the compressed file: a small zip bomb is refused).
MAX_NPZ_BYTES = 2 * 1024 ** 3
#: Most entries of an ``.npz`` file read.
MAX_NPZ_MEMBERS = 1000


def _check_npz_members(path: Path, bad, max_bytes: int) -> None:
    """Refuse an archive whose entries would unpack to more than ``max_bytes``, or whose
    ``.npy`` headers announce more data than the entry holds (numpy allocates the announced
    size before reading), before anything is unpacked."""
    import zipfile
    with zipfile.ZipFile(path) as zf:
        infos = zf.infolist()
        if len(infos) > MAX_NPZ_MEMBERS:
            raise bad(f"{len(infos)} entries, more than {MAX_NPZ_MEMBERS}")
        total = sum(i.file_size for i in infos)
        if total > max_bytes:
            raise bad(f"its arrays unpack to {total} bytes, more than the {max_bytes} read")
        if "metadata.npy" not in {i.filename for i in infos}:
            raise bad("no metadata entry")
        for info in infos:
            with zf.open(info) as fh:
                fmt = np.lib.format
                version = fmt.read_magic(fh)
                header = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
                shape, _, dtype = header(fh)
                if dtype.hasobject:
                    raise bad(f"entry {info.filename} holds Python objects")
                size = int(np.prod(shape, dtype=object)) * dtype.itemsize
                if size > info.file_size:
                    raise bad(f"entry {info.filename} announces {size} bytes but holds {info.file_size}")


def read_npz(path, option: str = "path", what: str = "hubbeam file", max_bytes: int | None = None) -> tuple:
    """Read a file written by :func:`write_npz`.

    Parameters
    ----------
    path : str or Path
    option : str
        The argument's name as the caller spelled it (starts the error message).
    what : str
        What the file should be, for the error message (e.g. ``"hubbeam result file"``).
    max_bytes : int, optional
        Largest total uncompressed size of its entries [bytes] (default
        :data:`MAX_NPZ_BYTES`; checked on the archive's directory and the arrays' headers
        before anything is unpacked).

    Returns
    -------
    arrays : dict
        Name -> ndarray, every entry except ``metadata``.
    metadata : dict

    Raises
    ------
    ParameterError
        One line naming the file: missing or not a regular file, not an NPZ archive,
        object arrays, no ``metadata`` entry or metadata that is not a JSON object.
    """
    path = check_regular_file(path, option)

    def bad(reason):
        return ParameterError(f"{option}: {path} is not a {what} ({reason})")

    try:
        with open(path, "rb") as fh:
            magic = fh.read(4)
        if magic[:2] != b"PK":
            raise bad("not an NPZ archive")
        _check_npz_members(path, bad, MAX_NPZ_BYTES if max_bytes is None else max_bytes)
        with np.load(path, allow_pickle=False) as data:
            if "metadata" not in data.files:
                raise bad("no metadata entry")
            text = data["metadata"]
            arrays = {k: data[k] for k in data.files if k != "metadata"}
    except ParameterError:
        raise
    except Exception as exc:        # BadZipFile, OSError, EOFError, ValueError (pickles), ...
        detail = str(exc).splitlines()[0] if str(exc) else ""
        raise bad(f"{type(exc).__name__}: {detail}") from None
    if text.dtype.kind != "U" or text.ndim != 0:
        raise bad("metadata is not a string")
    try:
        metadata = json.loads(str(text))
    except ValueError as exc:
        raise bad(f"metadata is not JSON: {exc}") from None
    if not isinstance(metadata, dict):
        raise bad("metadata is not a JSON object")
    return arrays, metadata
