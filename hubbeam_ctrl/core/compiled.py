"""Generated C for the hot CasADi functions: compiled once, cached on disk, loaded as externals.

:func:`compile_function` takes a :class:`casadi.Function`, generates C with CasADi's
``CodeGenerator``, builds a shared library with the C compiler found on the machine
(``$CC``, else ``cc``, ``gcc`` or ``clang`` on ``PATH``) and loads it with
:func:`casadi.external`. The result is a drop-in replacement of the original function
(same inputs, outputs and numbers, evaluated 3-10x faster than in CasADi's virtual
machine).

Backends
--------
``"vm"``
    The function as it is, evaluated by CasADi's virtual machine.
``"compiled"``
    Generated C, as above.
``"auto"``
    ``"compiled"`` when a compiler works, else ``"vm"``.

A compiler that is missing, fails or runs longer than ``$HUBBEAM_CC_TIMEOUT`` seconds
(default 900) never raises: the function falls back to ``"vm"`` and one line on stderr
names the reason. ``backend=None`` reads ``$HUBBEAM_BACKEND`` (default ``"auto"``).

Build cache
-----------
Shared libraries are kept in :func:`cache_dir` (``$HUBBEAM_CACHE_DIR``, else the
platform's cache folder, e.g. ``~/.cache/hubbeam-ctrl``), named by a SHA-256 of the
generated C, the compiler flags, the compiler's version and CasADi's version, so a second
process, a notebook restart or a sweep worker loads the library instead of compiling it.
:func:`hubbeam_ctrl.core.recipes.compile_recipe` goes one step further for functions built the same way every time
(the plant step of a model family, size and settings): a side file names the library by the
recipe and a digest of the package sources that build the function, so a later process loads
the library without building the CasADi graph or generating its C (a tenth of a second to
half a second per plant; see ``benchmarks/bench_simulate.py``).
Each library has a JSON side file with the SHA-256 of its bytes: a corrupt or foreign
file is detected and rebuilt. Builds run in a private temporary folder and are moved into
place with an atomic rename, under a per-entry file lock, so two processes building the
same entry at once compile it once and both load it. A cache folder that cannot be
written is replaced by a temporary folder (one line says so). Compiling shows a progress
line (tqdm) when it takes more than a second.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import platform
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from functools import lru_cache
from pathlib import Path

import casadi as ca

from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.linked_solvers import LinkError, solver_link_flags

__all__ = ["BACKENDS", "OPT_HOT", "OPT_HOT_MAX_CHARS", "OPT_HOT_LARGE", "OPT_COLD", "check_backend",
           "resolve_backend", "cache_dir", "find_compiler", "compile_function", "cache_info", "clear_cache",
           "CompileError"]

#: Accepted values of every ``backend`` argument.
BACKENDS = ("auto", "compiled", "vm")
#: Optimisation flag of functions called at every step (the residual, the plant step). -O3
#: against -O1 (plant step, one 10 ms sample, 30 substeps): FOAM 5+5 11.5 -> 9.7 us, FOAM 10+10
#: 38.2 -> 27.6 us, CFOAM 5+5 42.8 -> 38.6 us, for 1-2 s more compiling; sources longer than
#: :data:`OPT_HOT_MAX_CHARS` get :data:`OPT_HOT_LARGE` instead.
OPT_HOT = "-O3"
#: Generated C longer than this [characters] is compiled with :data:`OPT_HOT_LARGE` where
#: :data:`OPT_HOT` is asked (CFOAM 10+10: minutes at -O1 already).
OPT_HOT_MAX_CHARS = 1_000_000
#: The flag that replaces :data:`OPT_HOT` on large sources.
OPT_HOT_LARGE = "-O1"
#: Optimisation flag of rarely called functions (iteration matrices, Jacobians): -O1 and
#: above cost minutes on CFOAM's Jacobians and buy nothing measurable.
OPT_COLD = "-O0"

ENV_BACKEND = "HUBBEAM_BACKEND"
ENV_CACHE = "HUBBEAM_CACHE_DIR"
ENV_TIMEOUT = "HUBBEAM_CC_TIMEOUT"
#: Overrides the flag of the functions called at every step (:data:`OPT_HOT` and
#: :data:`OPT_HOT_LARGE`): ``-O0`` compiles a large function several times faster (the learning
#: NMPC's step, 1.6 MB of C: 10 s at -O0 against 84 s at -O1) for a slower step.
ENV_OPT = "HUBBEAM_CC_OPT"
#: The flags :data:`ENV_OPT` may hold.
OPT_FLAGS = ("-O0", "-O1", "-O2", "-O3", "-Os")
_DEFAULT_TIMEOUT_S = 900.0
_SUFFIX = ".dll" if os.name == "nt" else ".so"

#: Libraries loaded in this process, by cache key (a library is loaded once per process).
_LOADED: dict = {}
#: ``(id(f), opt, jacobian, compiler, folder) -> (f, loaded)``: skips generating C again for a
#: function object already handled (``f`` is held so that its id stays unique).
_BY_OBJECT: dict = {}
#: Notices printed in this process (each is printed once).
_NOTICES: set = set()


class CompileError(HubbeamError):
    """The C compiler is missing, failed or timed out (the message says which)."""


def _notice(text: str) -> None:
    if text not in _NOTICES:
        _NOTICES.add(text)
        print(f"hubbeam: {text}", file=sys.stderr, flush=True)


def check_backend(backend, name: str = "backend") -> str:
    """Validate a backend name.

    Parameters
    ----------
    backend : {"auto", "compiled", "vm"}
    name : str
        How the caller spells the parameter (for the error message).

    Returns
    -------
    str

    Raises
    ------
    ParameterError
        If ``backend`` is not one of :data:`BACKENDS`.
    """
    if not isinstance(backend, str) or backend not in BACKENDS:
        raise ParameterError(f"{name} must be one of {', '.join(BACKENDS)}, got {backend!r}")
    return backend


def resolve_backend(backend=None, name: str = "backend") -> str:
    """The backend to use: ``backend``, or ``$HUBBEAM_BACKEND`` (default ``"auto"``) for None.

    Parameters
    ----------
    backend : {"auto", "compiled", "vm"} or None
    name : str
        How the caller spells the parameter.

    Returns
    -------
    str
    """
    if backend is None:
        return check_backend(os.environ.get(ENV_BACKEND, "auto"), ENV_BACKEND)
    return check_backend(backend, name)


# -- cache folder --------------------------------------------------------------------------
def _platform_cache_root() -> Path:
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches"
    if os.name == "nt":
        return Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")


def cache_dir() -> Path:
    """Folder of the build cache: ``$HUBBEAM_CACHE_DIR`` or the platform's cache folder.

    Returns
    -------
    Path
        E.g. ``~/.cache/hubbeam-ctrl`` on Linux (it may not exist yet).
    """
    env = os.environ.get(ENV_CACHE)
    return Path(env).expanduser() if env else _platform_cache_root() / "hubbeam-ctrl"


@lru_cache(maxsize=None)
def _temporary_cache() -> Path:
    return Path(tempfile.mkdtemp(prefix="hubbeam-cache-"))


def _writable_cache_dir() -> Path:
    """The cache folder, created if needed; a temporary folder (with a notice) if unwritable."""
    folder = cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = tempfile.NamedTemporaryFile(dir=folder, prefix=".probe-", delete=True)
        probe.close()
        return folder
    except OSError as exc:
        tmp = _temporary_cache()
        _notice(f"cache folder {folder} is not writable ({exc.strerror or exc}); "
                f"compiling to the temporary folder {tmp}")
        return tmp


# -- compiler --------------------------------------------------------------------------------
def find_compiler() -> list:
    """The C compiler command: ``$CC`` (split like a shell), else ``cc``/``gcc``/``clang``.

    Returns
    -------
    list of str
        Command and leading arguments.

    Raises
    ------
    CompileError
        If no compiler is found (the message says where it looked).
    """
    env = os.environ.get("CC", "").strip()
    if env:
        cmd = shlex.split(env)
        exe = shutil.which(cmd[0])
        if exe is None:
            raise CompileError(f"C compiler CC={env!r} not found")
        return [exe] + cmd[1:]
    for name in ("cc", "gcc", "clang"):
        exe = shutil.which(name)
        if exe:
            return [exe]
    raise CompileError("no C compiler found (set CC or install cc/gcc/clang)")


@lru_cache(maxsize=8)
def _compiler_identity(cmd: tuple) -> str:
    """First line of ``cc --version`` (or the file's size and time), part of the cache key.

    Kept in the cache folder by the compiler's resolved path, size and time, so that a process
    does not run the compiler (10-20 ms) only to name it.
    """
    try:
        exe = os.path.realpath(cmd[0])
        st = os.stat(exe)
    except OSError:
        return _ask_compiler(cmd)
    stamp = f"{exe} {st.st_size} {st.st_mtime_ns} {' '.join(cmd[1:])}"
    memo = cache_dir() / f"compiler-{hashlib.sha256(stamp.encode()).hexdigest()[:24]}.txt"
    with contextlib.suppress(OSError, UnicodeError):
        text = memo.read_text(encoding="utf-8").splitlines()
        if len(text) == 2 and text[0] == stamp and text[1]:
            return text[1]
    identity = _ask_compiler(cmd)
    with contextlib.suppress(OSError):
        memo.parent.mkdir(parents=True, exist_ok=True)
        tmp = memo.with_name(f".{memo.name}.{os.getpid()}")
        tmp.write_text(f"{stamp}\n{identity}\n", encoding="utf-8")
        os.replace(tmp, memo)
    return identity


def _ask_compiler(cmd: tuple) -> str:
    """First line of ``cc --version``, or the file's size and time when it says nothing."""
    try:
        out = subprocess.run(list(cmd) + ["--version"], capture_output=True, text=True, timeout=30)
        line = (out.stdout or out.stderr).strip().splitlines()
        if out.returncode == 0 and line:
            return line[0]
    except (OSError, subprocess.SubprocessError):
        pass
    st = os.stat(cmd[0])
    return f"{cmd[0]} {st.st_size} {st.st_mtime_ns}"


def _hot_flag_override() -> str | None:
    """The flag ``$HUBBEAM_CC_OPT`` asks for the hot functions, or None when it is unset."""
    text = os.environ.get(ENV_OPT)
    if not text:
        return None
    if text not in OPT_FLAGS:
        raise ParameterError(f"{ENV_OPT} must be one of {', '.join(OPT_FLAGS)}, got {text!r}")
    return text


def _timeout_s() -> float:
    text = os.environ.get(ENV_TIMEOUT)
    if not text:
        return _DEFAULT_TIMEOUT_S
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value > 0:
        raise ParameterError(f"{ENV_TIMEOUT} must be a number of seconds > 0, got {text!r}")
    return value


class _CompileProgress:
    """Elapsed time of a compilation on stderr, shown once it has run for a second.

    A terminal gets a live tqdm line; a log or a pipe gets one line when it starts to be
    shown and one when it ends.
    """

    def __init__(self, label: str):
        self.label, self.start, self.bar, self.shown = label, time.perf_counter(), None, False

    def tick(self) -> None:
        if self.bar is not None:
            self.bar.refresh()
        elif not self.shown:
            self.shown = True
            if sys.stderr.isatty():
                from tqdm.auto import tqdm
                self.bar = tqdm(desc=f"compiling {self.label}", file=sys.stderr, leave=False,
                                bar_format="{desc}: {elapsed}")
            else:
                print(f"hubbeam: compiling {self.label} ...", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        if self.shown:
            print(f"hubbeam: compiled {self.label} in {time.perf_counter() - self.start:.1f} s",
                  file=sys.stderr, flush=True)


def _kill(proc) -> None:
    """Stop a compiler and everything it started (its own process group on POSIX)."""
    if os.name == "posix":
        import signal
        with contextlib.suppress(OSError):
            os.killpg(proc.pid, signal.SIGKILL)
    proc.kill()
    proc.communicate()


def _run_compiler(args: list, label: str, timeout: float) -> None:
    """Run one compiler command; show progress after a second; raise CompileError on failure."""
    start = time.perf_counter()
    try:
        proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                start_new_session=os.name == "posix")
    except OSError as exc:
        raise CompileError(f"C compiler {args[0]} could not be started ({exc.strerror or exc})") from None
    progress = _CompileProgress(label)
    try:
        while True:
            try:
                _, err = proc.communicate(timeout=1.0 if not progress.shown else 0.25)
                break
            except subprocess.TimeoutExpired:
                if time.perf_counter() - start > timeout:
                    _kill(proc)
                    raise CompileError(f"C compiler {Path(args[0]).name} timed out after {timeout:g} s "
                                       f"on {label} (raise {ENV_TIMEOUT})") from None
                progress.tick()
    finally:
        progress.close()
        if proc.poll() is None:
            _kill(proc)
    if proc.returncode != 0:
        first = next((ln for ln in err.splitlines() if ln.strip()), f"exit status {proc.returncode}")
        raise CompileError(f"C compiler {Path(args[0]).name} failed on {label}: {first.strip()[:160]}")


# -- sources, keys, entries --------------------------------------------------------------
def _sources(f: ca.Function, opt: str, jacobian: str | None, jacobian_function=None) -> list:
    """``[(function name, C source, flags)]``: ``f`` and, if asked, ``jac_<name>``."""
    funcs = [(f, opt)]
    if jacobian is not None:
        jf = f.jacobian() if jacobian_function is None else jacobian_function
        if jf.name() != f"jac_{f.name()}":
            raise ParameterError(f"jacobian_function must be named jac_{f.name()}, got {jf.name()!r}")
        funcs.append((jf, jacobian))
    out = []
    override = _hot_flag_override()
    for g, flags in funcs:
        cg = ca.CodeGenerator(f"{g.name()}.c", {"with_header": False})
        cg.add(g)
        src = cg.dump()
        if flags == OPT_HOT and override is not None:
            flags = override
        elif flags == OPT_HOT and len(src) > OPT_HOT_MAX_CHARS:
            flags = OPT_HOT_LARGE
        out.append((g.name(), src, flags))
    return out


def _key(sources: list, compiler: list) -> str:
    h = hashlib.sha256()
    for part in (ca.__version__, platform.machine(), sys.platform, _compiler_identity(tuple(compiler)),
                 " ".join(compiler[1:])):
        h.update(part.encode() + b"\0")
    for name, src, flags in sources:
        h.update(f"{name}\0{flags}\0".encode() + src.encode() + b"\0")
    return h.hexdigest()


def _file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _entry_paths(folder: Path, name: str, key: str) -> tuple:
    stem = f"{name}-{key[:24]}"
    return folder / f"{stem}{_SUFFIX}", folder / f"{stem}.json"


def _valid_entry(lib: Path, meta: Path, key: str) -> bool:
    """True when ``lib`` exists, its side file names ``key`` and its bytes hash as recorded."""
    try:
        info = json.loads(meta.read_text(encoding="utf-8"))
        return info.get("key") == key and _file_sha256(lib) == info.get("sha256")
    except (OSError, ValueError, AttributeError):
        return False


@contextlib.contextmanager
def _lock(path: Path):
    """An exclusive advisory lock on ``path`` (a no-op where ``fcntl`` does not exist)."""
    try:
        import fcntl
    except ImportError:                        # Windows: the atomic rename alone
        yield
        return
    with open(path, "a+") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _build(sources: list, compiler: list, lib: Path, meta: Path, key: str) -> None:
    """Compile ``sources`` into ``lib`` (atomically) and write its side file."""
    timeout = _timeout_s()
    pic = [] if os.name == "nt" else ["-fPIC"]
    try:
        linked = [solver_link_flags(src) for _, src, _ in sources]
    except LinkError as exc:              # the VM then (compile_function's fallback)
        raise CompileError(str(exc)) from None
    libs = list(dict.fromkeys(f for _, fs in linked for f in fs))
    with tempfile.TemporaryDirectory(dir=lib.parent, prefix=".build-") as tmp:
        objects = []
        for (name, src, flags), (includes, _) in zip(sources, linked):
            c_file = Path(tmp) / f"{name}.c"
            c_file.write_text(src, encoding="utf-8")
            obj = c_file.with_suffix(".o")
            _run_compiler(compiler + [flags, *pic, *includes, "-c", str(c_file), "-o", str(obj)],
                          f"{name} ({flags})", timeout)
            objects.append(str(obj))
        out = Path(tmp) / lib.name
        _run_compiler(compiler + ["-shared", *objects, *libs, "-o", str(out), "-lm"], f"{lib.name} (link)", timeout)
        info = {"key": key, "sha256": _file_sha256(out), "functions": [s[0] for s in sources],
                "flags": [s[2] for s in sources], "casadi": ca.__version__,
                "compiler": _compiler_identity(tuple(compiler)), "created": time.time()}
        side = Path(tmp) / meta.name
        side.write_text(json.dumps(info, indent=1), encoding="utf-8")
        os.replace(out, lib)
        os.replace(side, meta)


def _load(f: ca.Function, lib: Path) -> ca.Function:
    """``casadi.external`` of ``f``'s name in ``lib``, checked against ``f``'s signature."""
    g = ca.external(f.name(), str(lib))
    same = (g.n_in() == f.n_in() and g.n_out() == f.n_out()
            and all(g.sparsity_in(i) == f.sparsity_in(i) for i in range(f.n_in()))
            and all(g.sparsity_out(i) == f.sparsity_out(i) for i in range(f.n_out())))
    if not same:
        raise CompileError(f"{lib.name} does not hold {f.name()} with its signature")
    return g


def _compiled(f: ca.Function, opt: str, jacobian: str | None, jacobian_function) -> ca.Function:
    compiler = find_compiler()
    memo = (id(f), opt, jacobian, id(jacobian_function), tuple(compiler), str(cache_dir()))
    hit = _BY_OBJECT.get(memo)
    if hit is not None and hit[0] is f and hit[1] is jacobian_function and _LOADED.get(hit[3]) is hit[2]:
        return hit[2]
    g, key = _compiled_by_source(f, opt, jacobian, jacobian_function, compiler)
    _BY_OBJECT[memo] = (f, jacobian_function, g, key)
    return g


def _compiled_by_source(f: ca.Function, opt: str, jacobian: str | None, jacobian_function,
                        compiler: list) -> tuple:
    sources = _sources(f, opt, jacobian, jacobian_function)
    key = _key(sources, compiler)
    if key in _LOADED:
        return _LOADED[key], key
    folder = _writable_cache_dir()
    lib, meta = _entry_paths(folder, f.name(), key)
    g = None
    if _valid_entry(lib, meta, key):
        with contextlib.suppress(RuntimeError, CompileError):
            g = _load(f, lib)
    if g is None:
        with _lock(lib.with_suffix(".lock")):
            if not _valid_entry(lib, meta, key):      # another process may have built it meanwhile
                _build(sources, compiler, lib, meta, key)
        try:
            g = _load(f, lib)
        except RuntimeError as exc:
            raise CompileError(f"{lib.name} could not be loaded ({str(exc).splitlines()[0][:120]})") from None
    _LOADED[key] = g
    return g, key


def compile_function(f: ca.Function, backend=None, *, opt: str = OPT_HOT,
                     jacobian: str | None = None, jacobian_function: ca.Function | None = None) -> ca.Function:
    """``f`` as generated C loaded by ``casadi.external``, or ``f`` itself on the ``vm`` backend.

    Parameters
    ----------
    f : casadi.Function
        Any function CasADi can generate C for.
    backend : {"auto", "compiled", "vm"}, optional
        Default: ``$HUBBEAM_BACKEND`` or ``"auto"``. Both ``"auto"`` and ``"compiled"`` fall
        back to ``f`` (one line on stderr names the reason) when the compiler is missing,
        fails or times out.
    opt : str
        Compiler flag of ``f`` (:data:`OPT_HOT` for functions called at every step,
        :data:`OPT_COLD` for rarely called ones).
    jacobian : str, optional
        Also compile ``f.jacobian()`` (named ``jac_<name>``) with this flag, so that CasADi
        differentiates the external function (e.g. inside IDAS) in C as well.
    jacobian_function : casadi.Function, optional
        What to compile as ``jac_<name>`` instead of ``f.jacobian()`` (same inputs and
        outputs; e.g. with the blocks of constant inputs left structurally zero).

    Returns
    -------
    casadi.Function
        Same inputs, outputs and sparsity as ``f``.

    Examples
    --------
    >>> import casadi as ca
    >>> x = ca.SX.sym("x", 2)
    >>> f = ca.Function("twice", [x], [2 * x])
    >>> compile_function(f, "vm") is f
    True
    """
    if not isinstance(f, ca.Function):
        raise ParameterError(f"f must be a casadi.Function, got {type(f).__name__}")
    if resolve_backend(backend) == "vm":
        return f
    try:
        return _compiled(f, opt, jacobian, jacobian_function)
    except CompileError as exc:
        _notice(f"{exc}; using the CasADi VM")
        return f


# -- cache maintenance --------------------------------------------------------------------------
def cache_info() -> dict:
    """What the build cache holds.

    Returns
    -------
    dict
        ``folder``, ``libraries`` (count), ``bytes`` (total size of all its files) and
        ``entries`` (name, size [bytes], functions and flags of each library).
    """
    folder = cache_dir()
    entries, total = [], 0
    if folder.is_dir():
        for p in sorted(folder.iterdir()):
            if p.is_file():
                total += p.stat().st_size
            if p.suffix == _SUFFIX:
                try:
                    info = json.loads(p.with_suffix(".json").read_text(encoding="utf-8"))
                except (OSError, ValueError):
                    info = {}
                entries.append({"file": p.name, "bytes": p.stat().st_size,
                                "functions": info.get("functions", []), "flags": info.get("flags", [])})
    return {"folder": str(folder), "libraries": len(entries), "bytes": total, "entries": entries}


def clear_cache() -> int:
    """Delete every library, side file and lock of the build cache.

    Returns
    -------
    int
        Number of files removed. Libraries already loaded by running processes stay valid.
    """
    folder = cache_dir()
    removed = 0
    if not folder.is_dir():
        return 0
    for p in folder.iterdir():
        if p.is_file() and p.suffix in (_SUFFIX, ".json", ".lock"):
            p.unlink()
            removed += 1
        elif p.is_dir() and p.name.startswith(".build-"):
            shutil.rmtree(p, ignore_errors=True)
        elif p.is_dir() and p.name == "results":          # arrays of hubbeam_ctrl.core.stored
            for f in p.glob("*.np[yz]"):
                f.unlink()
                removed += 1
    _LOADED.clear()
    return removed
