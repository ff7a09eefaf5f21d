"""Software in the loop: the generated C controller compiled, loaded and run by the simulator.

:func:`compile_c` builds a shared library from :func:`~hubbeam_ctrl.deploy.to_c`'s sources
with the system C compiler and the strict flags ``-std=c99 -Wall -Wextra -pedantic
-Werror``; :class:`CController` loads it with :mod:`ctypes` and is a controller of
:func:`hubbeam_ctrl.sim.closedloop.simulate_closed_loop` (it carries the Python
controller's ``dt``, ``design``, ``n_modes`` and ``measurement``, so the simulator picks the
same evaluation plant). Without a C compiler, :func:`compiler` says so in one line.
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import tempfile
from pathlib import Path

from hubbeam_ctrl.core.compiled import CompileError
from hubbeam_ctrl.core.errors import ParameterError

from .codegen import GeneratedCode

__all__ = ["STRICT_FLAGS", "NO_COMPILER", "compiler", "compile_c", "CController"]

#: Flags every generated source must compile with, warning-free.
STRICT_FLAGS = ("-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror")

#: The one line said when there is no C compiler.
NO_COMPILER = "no C compiler (cc) found: the C sources are written, the software-in-the-loop check needs one"


def compiler() -> str | None:
    """Path of the system C compiler ``cc`` (or ``gcc``, ``clang``), None when there is none."""
    for exe in ("cc", "gcc", "clang"):
        path = shutil.which(exe)
        if path:
            return path
    return None


def compile_c(code: GeneratedCode | Path | str, opt: str = "-O2", out_dir=None, name: str | None = None,
              timeout_s: float = 120.0) -> Path:
    """Compile generated C into a shared library with :data:`STRICT_FLAGS`.

    Parameters
    ----------
    code : GeneratedCode or path
        What :func:`~hubbeam_ctrl.deploy.to_c` returned (written to a folder), or the folder
        holding ``<name>.c``.
    opt : {"-O0", "-O1", "-O2", "-O3", "-Os"}
        Optimisation level.
    out_dir : str or Path, optional
        Where the library goes (default: a new temporary folder).
    name : str, optional
        The file stem when ``code`` is a folder.
    timeout_s : float
        Compiler time limit [s].

    Returns
    -------
    Path
        The shared library ``lib<name><opt>.so``.

    Raises
    ------
    CompileError
        No compiler (:data:`NO_COMPILER`), or the compiler failed (its first message line).
    """
    if opt not in ("-O0", "-O1", "-O2", "-O3", "-Os"):
        raise ParameterError(f"opt must be one of -O0, -O1, -O2, -O3, -Os, got {opt!r}")
    if isinstance(code, GeneratedCode):
        if code.folder is None:
            raise ParameterError("code: write the sources first (to_c(controller, out_dir))")
        folder, name = Path(code.folder), code.name
    else:
        folder = Path(code)
        if name is None:
            raise ParameterError("name: give the file stem when code is a folder")
    cc = compiler()
    if cc is None:
        raise CompileError(NO_COMPILER)
    out = Path(tempfile.mkdtemp(prefix="hubbeam-sil-")) if out_dir is None else Path(out_dir)
    lib = out / f"lib{name}{opt}.so"
    args = [cc, *STRICT_FLAGS, opt, "-fPIC", "-shared", str(folder / f"{name}.c"), "-o", str(lib), "-lm"]
    try:
        proc = subprocess.run(args, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        raise CompileError(f"C compiler timed out after {timeout_s:g} s on {name}.c") from None
    if proc.returncode != 0:
        first = next((ln for ln in proc.stderr.splitlines() if ln.strip()), f"exit status {proc.returncode}")
        raise CompileError(f"C compiler failed on {name}.c {opt}: {first.strip()[:200]}")
    return lib


class CController:
    """A compiled generated controller as a controller of the closed-loop simulator.

    Parameters
    ----------
    library : str or Path
        The shared library from :func:`compile_c`.
    code : GeneratedCode
        Its sources' description (name, sensors, reference length).
    python_controller : controllers.Controller, optional
        The controller it was generated from: its ``dt``, ``design``, ``n_modes`` and
        ``state_modes`` are copied so the simulator chooses the same evaluation plant.

    Attributes
    ----------
    name : str
        ``"<name>_c"``.
    measurement : {"sensors", "state"}
        ``"sensors"`` for feedback controllers (they read only the hub sensors).
    """

    def __init__(self, library, code: GeneratedCode, python_controller=None):
        self.code = code
        self._lib = ctypes.CDLL(str(library))
        prefix = code.name
        size = getattr(self._lib, f"{prefix}_instance_size")
        size.restype = ctypes.c_ulong
        self._inst = ctypes.create_string_buffer(int(size()))
        self._init = getattr(self._lib, f"{prefix}_init")
        self._reset = getattr(self._lib, f"{prefix}_reset")
        self._step = getattr(self._lib, f"{prefix}_step")
        self._applied = getattr(self._lib, f"{prefix}_applied")
        self._applied.argtypes = [ctypes.c_void_p, ctypes.c_double]
        self._applied.restype = None
        dbl_p = ctypes.POINTER(ctypes.c_double)
        self._step.argtypes = [ctypes.c_void_p, dbl_p, dbl_p, dbl_p]
        self._step.restype = None
        n_meas = max(len(code.law.sensors), 1)
        self._y = (ctypes.c_double * max(n_meas, 3))()
        self._n_meas = n_meas
        self._tau = ctypes.c_double(0.0)
        self._tau_p = ctypes.pointer(self._tau)
        self._y_p = ctypes.cast(self._y, dbl_p)
        self._null = ctypes.cast(None, dbl_p)
        self.name = f"{prefix}_c"
        self.dt = code.law.dt
        self.measurement = "sensors" if code.law.sensors else "state"
        #: the rig signals the step reads (None: the closed loop's default three), as the Python law's
        self.signals = None if (code.law.kind == "pd" or tuple(code.law.sensors) == (
            "theta", "theta_dot", "root_moment")) else tuple(code.law.sensors)
        if python_controller is not None and getattr(python_controller, "signals", None) is not None:
            self.signals = tuple(python_controller.signals)
        self._k = 0
        if python_controller is not None:
            for attr in ("design", "n_modes", "state_modes"):
                if hasattr(python_controller, attr):
                    setattr(self, attr, getattr(python_controller, attr))
        self._init(self._inst)

    def reset(self) -> None:
        """``<name>_reset``: a new run from sample 0."""
        self._reset(self._inst)
        self._k = 0

    def __call__(self, t: float, y) -> float:
        """``<name>_step`` with the measurement ``y``; the hub torque [N m].

        Parameters
        ----------
        t : float
            Time [s]; must be the next sample ``k dt`` (the C code counts samples).
        y : array_like
            Measurements in the order of ``code.law.sensors``.
        """
        if abs(t - self._k * self.dt) > 1e-9 * max(1.0, abs(t)):
            raise ParameterError(f"t: the C controller expects the next sample t = {self._k * self.dt:g} s, "
                                 f"got {t:g} s")
        if self.measurement == "sensors":
            for i in range(self._n_meas):
                self._y[i] = float(y[i])
        self._step(self._inst, self._y_p, self._null, self._tau_p)
        self._k += 1
        return self._tau.value

    def applied(self, command: float) -> None:
        """``<name>_applied``: the drive gave ``command``, not what the step returned (a slew-rate limit).

        Parameters
        ----------
        command : float
            The command applied [N m].
        """
        self._applied(self._inst, float(command))

    def step(self, y, reference=None) -> float:
        """One raw ``<name>_step`` call, without the time check (for benchmarks and tests).

        Parameters
        ----------
        y : array_like
            Measurements in the order of ``code.law.sensors`` [rad, rad/s, N m].
        reference : array_like, optional
            The external reference vector (``code.law.n_reference`` values, layout in the
            header); None: the built-in table.

        Returns
        -------
        float
            The command [N m].
        """
        for i in range(self._n_meas):
            self._y[i] = float(y[i])
        ref = self._null if reference is None else (ctypes.c_double * len(reference))(*reference)
        self._step(self._inst, self._y_p, ref, self._tau_p)
        return self._tau.value

    def stats(self) -> dict:
        """Nothing counted (the generated code keeps no statistics)."""
        return {}
