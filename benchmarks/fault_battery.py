"""Issue 37's fault battery: bad values, bad files, damaged rigs and bad outputs on every command, each classed.

Run (one process at a time; each case is forked from this one, with a timeout)::

    .venv/bin/python benchmarks/fault_battery.py [--only compare,excite] [--timeout 60] [--out FILE]

The commands and their options are read from ``hubbeam``'s parser, so a command or option added later is
battered too. Each command starts from a cheap valid command line (:data:`BASES`); a case sets one option
(``--opt=VALUE``, every option: 0, -1, nan, inf, -inf, 1e308, 1e-300, 2^63, '', text, a list), gives a file
option a bad file (missing, a folder, /dev/zero, a FIFO, binary, non-UTF-8, bad TOML/CSV/JSON, > 1 MB, a
256-character name, a path past PATH_MAX, unreadable), an output option a bad place (read-only, a file
where a folder goes and the reverse, a missing folder, a full disk: a 64 kB tmpfs, when this user can
mount one) or damages one key of a rig file (every field of every table: wrong type, out of range, nan,
missing, and an unknown key per table). An interrupted sweep resumed must give the uninterrupted result.

Classes: ``refused`` (status 2, one line, names the option or rig key as typed), ``refused_other`` (the
same, naming another option typed with it, the one it conflicts with: ``--slew-angle=-1`` with ``--tf 1``
names ``--tf``; or any refusal of a rig missing a key, which cannot name what is not there), ``wrong_name``
(status 2, one line, naming none of the options typed), ``traceback`` (a traceback, an exception's name with
status 1, or a crash), ``hang`` (past the timeout), ``silent_wrong`` (status 0 for a value no range allows:
nan, inf, 1e308, 2^63, text, a list, a wrong type, an unknown key), ``accepted`` (status 0 for a value
some ranges allow: 0, -1, 1e-300, a missing rig key; listed for review), ``failed`` (status 1, no
exception: the run failed or judged, e.g. a full disk, certify's "not certified"), ``lost`` (a resumed
sweep that lost or changed results). Classes 3-6 of the issue are ``traceback``, ``hang``,
``silent_wrong`` and ``lost``; ``wrong_name`` breaks its naming rule.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

#: The code battered: this checkout, or ``--code DIR`` (e.g. an export of the commit before the fixes).
CODE = os.path.abspath(next((a.split("=", 1)[1] for a in sys.argv if a.startswith("--code=")),
                            os.path.join(os.path.dirname(__file__), "..")))
sys.path.insert(0, CODE)
os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

SPEC = ('[study]\ncontrollers = ["lqr"]\nt_f = 1.0\nt_end = 2.5\ndt = 0.01\nplant_modes = 1\n'
        '[params]\nn_axial = 1\nn_transverse = 1\n[grid]\nm_t = [0.1]\n')
MODAL = "spin [rad/s],m_t [kg],mode [-],frequency [Hz],damping [-]\n0,0.0,1,2.0,0.01\n0,0.0,2,12.0,0.01\n"

#: A cheap valid command line per command; ``{in}`` is the folder of the good and bad inputs.
BASES = {
    "modes": ["modes", "--n-modes", "2"],
    "critical-speed": ["critical-speed", "--n-modes", "2"],
    "simulate": ["simulate", "--model", "sfoam", "--maneuver", "torque", "--t-end", "0.1", "--n-modes", "1"],
    "linearize": ["linearize", "--n-modes", "2", "--out", "lin.json"],
    "compare": ["compare", "--controllers", "lqr", "--n-modes", "2", "--tf", "1", "--t-end", "2", "--out", "c"],
    "design": ["design", "--controller", "lqr", "--n-modes", "2", "--out", "d.json"],
    "sweep": ["sweep", "{in}/spec.toml", "--out", "s", "--workers", "1"],
    "tune": ["tune", "{in}/spec.toml", "--controller", "lqr", "--out", "t", "--workers", "1", "--maxiter", "1",
             "--popsize", "2"],
    "cache": ["cache", "info"],
    "optimal": ["optimal", "--slew-angle", "1", "--n-modes", "1"],
    "fmu": ["fmu", "--n-modes", "1", "--out", "x.fmu"],
    "demo": ["demo", "--out", "demo_out"],
    "codegen": ["codegen", "--controller", "lqr", "--n-modes", "2", "--out", "cg"],
    "excite": ["excite", "--rig", "servo_link", "--kind", "step", "--duration", "0.1", "--out", "x.csv"],
    "identify": ["identify", "--modal-table", "{in}/modal.csv", "--rig", "servo_link", "--fit", "E", "--out",
                 "idout", "--max-evaluations", "2", "--force"],
    "certify": ["certify", "lqr", "--n-modes", "2", "--tf", "1", "--t-end", "2", "--dt", "0.01", "--uncertainty",
                "m_t=0:0.1", "--grid", "2", "--check", "none", "--out", "ce"],
}
#: Further command lines battered the same way (the controllers and options this stage added; a rig's
#: default task, which a slew without --tf takes from the rig), on the options of :data:`VARIANT_OPTIONS`.
VARIANTS = {
    "codegen nmpc": ["codegen", "--controller", "nmpc", "--n-modes", "1", "--out", "cg"],
    "codegen msmpc": ["codegen", "--controller", "msmpc", "--n-modes", "1", "--out", "cg"],
    "compare rig": ["compare", "--rig", "servo_link", "--controllers", "lqr", "--out", "c"],
    "design rig": ["design", "--controller", "lqr", "--rig", "servo_link", "--out", "d.json"],
}
VARIANT_OPTIONS = {"codegen nmpc": ("--controller", "--horizon", "--dt", "--tf", "--n-modes"),
                   "compare rig": ("--slew-angle", "--tf", "--dt", "--tip-mass", "--settle-angle", "--settle-tip"),
                   "design rig": ("--slew-angle", "--tf", "--dt", "--tip-mass")}
VARIANT_OPTIONS["codegen msmpc"] = VARIANT_OPTIONS["codegen nmpc"]
#: Options whose values run nothing but the whole command (the demo): only their file faults.
NO_VALUES = {("demo", "--out")}

VALUES = {"0": "0", "-1": "-1", "nan": "nan", "inf": "inf", "-inf": "-inf", "1e308": "1e308", "1e-300": "1e-300",
          "2^63": str(2 ** 63), "empty": "", "text": "text", "list": "1,2"}
#: Values some ranges allow (status 0 is listed for review, not counted as silent wrong).
MAYBE_VALID = {"0", "-1", "1e-300"}
FILE_OPTIONS = {"--params", "--rig", "--plant-params", "--settings", "spec", "records", "--modal-table",
                "--validate"}
OUT_OPTIONS = {"--out", "--plot", "--verbose", "--c-out"}
#: Options that take a name or text rather than a number (a text may be valid there).
TEXT_OK = {"--controllers", "--controller", "controller", "--scheduler", "--fit", "--sensors", "--plant"}


def make_inputs(d: str) -> dict:
    """Write the good and bad input files into ``d``; return the bad files by name."""
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "spec.toml"), "w") as fh:
        fh.write(SPEC)
    with open(os.path.join(d, "modal.csv"), "w") as fh:
        fh.write(MODAL)
    bad = {}

    def put(name, data: bytes):
        path = os.path.join(d, name)
        with open(path, "wb") as fh:
            fh.write(data)
        bad[name.split(".")[0]] = path
    put("binary.toml", bytes(range(256)) * 4)
    put("latin1.toml", b"\xb2 = 1\n")
    put("badtoml.toml", b"[beam]\nL = = 2\n")
    put("badcsv.csv", b"a,b\n1,2,3\n\"x\n")
    put("badjson.json", b"{\"a\": [1, 2\n")
    put("huge.toml", b"# " + b"x" * 4_100_000 + b"\n")        # past every reader's limit (specs: 4 MB)
    put("empty.toml", b"")
    os.mkdir(os.path.join(d, "adir"))
    bad["adir"] = os.path.join(d, "adir")
    os.mkfifo(os.path.join(d, "fifo.toml"))
    bad["fifo"] = os.path.join(d, "fifo.toml")
    put("unreadable.toml", b"[beam]\nm_t = 0.2\n")
    os.chmod(bad["unreadable"], 0)
    bad["missing"] = os.path.join(d, "missing.toml")
    bad["devzero"] = "/dev/zero"
    bad["longname"] = os.path.join(d, "a" * 256)
    bad["pastmax"] = "/".join(["b" * 200] * 25) + ".toml"
    return bad


def make_places(d: str) -> dict:
    """Bad output places in ``d``: a file where a folder goes, a folder where a file goes, a missing
    parent, a 256-character name, a path past PATH_MAX, /dev/full, and (root) a read-only and a full tmpfs."""
    places = {}
    with open(os.path.join(d, "afile"), "w") as fh:
        fh.write("x")
    places["file"] = os.path.join(d, "afile")
    os.makedirs(os.path.join(d, "outdir.json"), exist_ok=True)
    places["folder"] = os.path.join(d, "outdir.json")
    places["noparent"] = os.path.join(d, "no", "such", "out.json")
    places["longname"] = os.path.join(d, "a" * 256)
    places["pastmax"] = "/".join(["c" * 200] * 25)
    places["devfull"] = "/dev/full"
    for name, opts in (("readonly", "ro,size=64k"), ("full", "size=64k")):
        mnt = os.path.join(d, name)
        os.makedirs(mnt, exist_ok=True)
        if subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", mnt], capture_output=True).returncode:
            continue
        if name == "full":
            with open(os.path.join(mnt, "filler"), "wb") as fh:    # leave ~2 kB free
                try:
                    fh.write(b"\0" * (62 * 1024))
                except OSError:
                    pass
        places[name] = os.path.join(mnt, "out.json")
    return places


def unmount(d: str) -> None:
    for name in ("readonly", "full"):
        subprocess.run(["umount", os.path.join(d, name)], capture_output=True)


def set_option(base: list, option: str, value: list) -> list:
    """``base`` with ``option`` (or a positional's place) given ``value`` (a list of tokens)."""
    argv = list(base)
    if option.startswith("-"):
        if option in argv:
            i = argv.index(option)
            del argv[i:i + 2]
        return argv + value
    return argv


def rig_cases(inputs: str) -> list:
    """Damage ``servo_link.toml`` key by key; each case runs ``excite --rig FILE`` (cheap)."""
    from dataclasses import fields

    from hubbeam_ctrl.plant.rig import RIG_TABLES
    base = open(os.path.join(CODE, "hubbeam_ctrl", "data", "rigs", "servo_link.toml")).read()
    tables = {}
    current = None
    for line in base.splitlines():
        m = re.match(r"^\[(\w+)\]", line)
        if m:
            current = m.group(1)
            tables[current] = []
        elif current and re.match(r"^\w+\s*=", line):
            tables[current].append(line.split("=")[0].strip())
    cases = []
    for table, cls in RIG_TABLES.items():
        for f in fields(cls):
            if f.name.startswith("_") or not f.init:
                continue
            key = f"{table}.{f.name}"
            for tag, value in (("text", '"text"'), ("-1", "-1"), ("nan", "nan"), ("inf", "inf"),
                               ("1e308", "1e308"), ("list", "[1, 2]"), ("table", "{ a = 1 }")):
                cases.append((key, tag, _with_key(base, table, f.name, value)))
            if f.name in tables.get(table, []):
                cases.append((key, "missing", _with_key(base, table, f.name, None)))
        cases.append((f"{table}.bogus", "unknown", _with_key(base, table, "bogus", "1")))
    cases.append(("bogus", "unknown", base + "\n[bogus]\nx = 1\n"))
    out = []
    for i, (key, tag, text) in enumerate(cases):
        path = os.path.join(inputs, f"rig_{i}.toml")
        with open(path, "w") as fh:
            fh.write(text)
        out.append(("rig", key, tag, ["excite", "--rig", path, "--kind", "step", "--duration", "0.1",
                                      "--out", "x.csv"]))
    return out


def _with_key(text: str, table: str, key: str, value) -> str:
    """The rig file ``text`` with ``table.key`` set to ``value`` (None: removed), the table added if missing."""
    lines, out, in_table, done = text.splitlines(), [], False, False
    for line in lines:
        m = re.match(r"^\[(\w+)\]", line)
        if m:
            if in_table and not done and value is not None:
                out.append(f"{key} = {value}")
                done = True
            in_table = m.group(1) == table
        elif in_table and re.match(rf"^{re.escape(key)}\s*=", line):
            done = True
            if value is not None:
                out.append(f"{key} = {value}")
            continue
        out.append(line)
    if not done and value is not None:
        if not in_table:
            out.append(f"[{table}]")
        out.append(f"{key} = {value}")
    return "\n".join(out) + "\n"


def cases(parser, only, inputs: str, bad: dict, places: dict) -> list:
    """Every case: ``(command, option, fault, argv)``."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    bases = dict(BASES)
    bases.update(VARIANTS)
    out = []
    for label, base in bases.items():
        cmd = base[0]
        if only and cmd not in only and label not in only:
            continue
        base = [t.replace("{in}", inputs) for t in base]
        for action in sub.choices[cmd]._actions:
            if isinstance(action, (argparse._HelpAction, argparse._StoreTrueAction)):
                continue
            option = action.option_strings[0] if action.option_strings else action.dest
            if label in VARIANTS and option not in VARIANT_OPTIONS[label]:
                continue
            positional = not action.option_strings
            if option in FILE_OPTIONS:
                for fault, path in bad.items():
                    out.append((label, option, f"file:{fault}", _place(base, option, path, positional)))
                continue
            if option in OUT_OPTIONS:
                for fault, path in places.items():
                    out.append((label, option, f"out:{fault}", _place(base, option, path, positional)))
                continue
            if (cmd, option) in NO_VALUES:
                continue
            for tag, value in VALUES.items():
                if positional:
                    argv = _place(base, option, value, True)
                elif tag == "empty":
                    argv = set_option(base, option, [option, value])
                else:
                    argv = set_option(base, option, [f"{option}={value}"])
                out.append((label, option, f"value:{tag}", argv))
    return out


def _place(base, option, value, positional):
    if positional:
        argv = list(base)
        if option == "records":                       # nargs="*": none in the base
            argv.insert(1, value)
        else:
            argv[1] = value
        return argv
    return set_option(base, option, [option, value])


def run_case(argv: list, timeout: float, work: str, unprivileged: bool = False) -> dict:
    """Run ``hubbeam argv`` in a forked child in the empty folder ``work`` (``unprivileged``: without
    root's override of file modes, :func:`drop_dac_override`); its status, stderr, stdout."""
    from hubbeam_ctrl.cli.main import main
    os.makedirs(work, exist_ok=True)
    err_path, out_path = os.path.join(work, "..", "err.txt"), os.path.join(work, "..", "out.txt")
    t0 = time.monotonic()
    pid = os.fork()
    if pid == 0:                                    # the child
        code = 99
        try:
            os.setpgrp()
            os.chdir(work)
            fd_out, fd_err = os.open(out_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC), \
                os.open(err_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
            os.dup2(fd_out, 1)
            os.dup2(fd_err, 2)
            if unprivileged:
                drop_dac_override()
            sys.stdout = open(1, "w", closefd=False)
            sys.stderr = open(2, "w", closefd=False)
            code = main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 0
        except BaseException:                        # noqa: BLE001 - what escapes main is a traceback
            import traceback
            traceback.print_exc()
            code = 98
        finally:
            try:
                sys.stdout.flush()
                sys.stderr.flush()
            finally:
                os._exit(code if isinstance(code, int) else 97)
    status = None
    while time.monotonic() - t0 < timeout:
        done, raw = os.waitpid(pid, os.WNOHANG)
        if done:
            status = os.waitstatus_to_exitcode(raw)
            break
        time.sleep(0.02)
    if status is None:
        try:
            os.killpg(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        os.waitpid(pid, 0)
    else:
        try:
            os.killpg(pid, signal.SIGKILL)           # worker processes left behind
        except (ProcessLookupError, PermissionError):
            pass
    wall = time.monotonic() - t0
    read = lambda p: open(p, errors="replace").read() if os.path.exists(p) else ""  # noqa: E731
    return {"status": status, "err": read(err_path), "out": read(out_path), "wall": round(wall, 2),
            "wrote": sorted(os.listdir(work))}


EXC = re.compile(r"hubbeam: error: (?:[\w.]+\.)?[A-Z]\w*(?:Error|Exception|Warning|Interrupt)\b")


def classify(case, result) -> str:
    """The class of one case (see the module docstring)."""
    label, option, fault, argv = case[:4]
    status, err = result["status"], result["err"]
    if status is None:
        return "hang"
    if "Traceback" in err or status in (97, 98, 99) or status < 0 or EXC.search(err):
        return "traceback"
    lines = [x for x in err.splitlines() if x.strip() and not x.startswith("hubbeam: note:")]
    if status == 2:
        if len(lines) != 1:
            return "traceback"
        if names(option, fault, lines[0]):
            return "refused"
        typed = [a.split("=")[0] for a in argv if a.startswith("--") and a.split("=")[0] != option]
        if fault == "rig:missing" or any(names(o, fault, lines[0]) for o in typed):
            return "refused_other"        # names another option typed with it: the one it conflicts with
        return "wrong_name"
    if status == 0:
        kind, _, tag = fault.partition(":")
        if kind == "value" and (tag in MAYBE_VALID or (tag == "text" and option in TEXT_OK)):
            return "accepted"
        if kind == "rig" and tag in ("-1", "missing"):
            return "accepted"
        if (kind == "out" and fault.endswith(("file", "folder", "full"))) or fault == "file:empty":
            return "accepted"
        return "silent_wrong"
    if status == 1:
        return "failed"               # the run failed or judged (certify: "not certified"), no exception
    return "traceback"


def names(option: str, fault: str, line: str) -> bool:
    """Whether the refusal names what was typed: the option, the rig key, or the file."""
    if fault.startswith("rig:"):
        key = option
        if key == "bogus" or key.endswith(".bogus"):
            return "bogus" in line
        return key in line
    if option.startswith("-"):
        return re.search(rf"(?<![\w-]){re.escape(option)}(?![\w-])", line) is not None
    return True                                       # a positional: the file's name or the value


def lost_case(tmp: str, timeout: float) -> dict:
    """A sweep interrupted (SIGINT once one case is on disk), resumed, against the same sweep run whole."""
    spec = os.path.join(tmp, "resume.toml")
    with open(spec, "w") as fh:
        fh.write(SPEC.replace("m_t = [0.1]", f"m_t = {[round(0.02 * k, 2) for k in range(1, 17)]}"))
    hide = "sys.modules['slycot'] = None; " if sys.modules.get("slycot", 0) is None else ""
    py = [sys.executable, "-c", f"import sys; {hide}from hubbeam_ctrl.cli.main import main; sys.exit(main())",
          "sweep", spec, "--workers", "1", "--json"]
    env = dict(os.environ, PYTHONPATH=CODE)
    t0 = time.monotonic()
    whole = subprocess.run(py + ["--out", os.path.join(tmp, "whole")], capture_output=True, env=env, timeout=timeout)
    wall = time.monotonic() - t0
    part = os.path.join(tmp, "part")
    # SIGINT as at a terminal: a battery started in the background (nohup, &) inherits it ignored
    proc = subprocess.Popen(py + ["--out", part], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    t0 = time.monotonic()
    done = os.path.join(part, "results.csv")
    while time.monotonic() - t0 < timeout and proc.poll() is None:
        if (os.path.exists(done) and open(done).read().count("\n") >= 3) or time.monotonic() - t0 > 0.5 * wall:
            break                     # two cases on disk (of 16), or half the whole run's time
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=timeout)
    interrupted = proc.returncode
    n_part = open(done).read().count("\n") - 1 if os.path.exists(done) else 0
    resumed = subprocess.run(py + ["--out", part, "--resume"], capture_output=True, env=env, timeout=timeout)

    def table(folder):
        """Each CSV's rows by their first column (the order of a resumed run differs), without timings."""
        import csv
        import glob
        tables = {}
        for f in sorted(glob.glob(os.path.join(folder, "*.csv"))):
            with open(f, newline="") as fh:
                rows = list(csv.DictReader(fh))
            tables[os.path.basename(f)] = sorted(
                tuple((k, v) for k, v in row.items() if not k.endswith(("_s", "_ms"))) for row in rows)
        return tables
    same = resumed.returncode == 0 and whole.returncode == 0 and table(os.path.join(tmp, "whole")) == table(part)
    return {"interrupted_status": interrupted, "cases_before_resume": n_part, "resumed_status": resumed.returncode,
            "whole_status": whole.returncode, "same_results": same,
            "files": sorted(table(part)), "err": resumed.stderr.decode()[-300:]}


def drop_dac_override() -> None:
    """Drop this process's CAP_DAC_OVERRIDE and CAP_DAC_READ_SEARCH (Linux ``capset``): root then meets
    file modes like any user, so an unreadable file is unreadable (root reads anything otherwise)."""
    import ctypes

    class Header(ctypes.Structure):
        _fields_ = [("version", ctypes.c_uint32), ("pid", ctypes.c_int)]

    class Data(ctypes.Structure):
        _fields_ = [("effective", ctypes.c_uint32), ("permitted", ctypes.c_uint32),
                    ("inheritable", ctypes.c_uint32)]
    libc = ctypes.CDLL(None, use_errno=True)
    header, data = Header(0x20080522, 0), (Data * 2)()          # _LINUX_CAPABILITY_VERSION_3
    if libc.capget(ctypes.byref(header), data) == 0:
        data[0].effective &= ~((1 << 1) | (1 << 2))
        libc.capset(ctypes.byref(header), data)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", help="commands (or variant labels, 'rig', 'resume') to run, comma separated")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per case (default 60)")
    ap.add_argument("--out", help="JSON file for the counts and the failing cases")
    ap.add_argument("--no-rig", action="store_true", help="skip the damaged rig files")
    ap.add_argument("--no-resume", action="store_true", help="skip the interrupted sweep")
    ap.add_argument("--list", action="store_true", help="print the failing cases as they come")
    ap.add_argument("--code", help="the checkout to batter (default this one); give it as --code=DIR")
    ap.add_argument("--no-slycot", action="store_true",
                    help="hide Slycot (python-control then leaves the Riccati equations to SciPy, as without it)")
    opts = ap.parse_args(argv)
    if opts.no_slycot:
        sys.modules["slycot"] = None                  # importlib.util.find_spec("slycot") is then None
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    only = set(opts.only.split(",")) if opts.only else set()

    import casadi  # noqa: F401 - imported once here, shared by the forked cases
    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401

    import hubbeam_ctrl
    from hubbeam_ctrl.cli.main import build_parser
    if not os.path.abspath(hubbeam_ctrl.__file__).startswith(CODE + os.sep):
        raise SystemExit(f"hubbeam_ctrl comes from {hubbeam_ctrl.__file__}, not {CODE}")
    tmp = tempfile.mkdtemp(prefix="fault_battery_")
    inputs = os.path.join(tmp, "in")
    bad = make_inputs(inputs)
    places = make_places(tmp)
    try:
        todo = cases(build_parser(), only, inputs, bad, places)
        if not opts.no_rig and (not only or "excite" in only or "rig" in only):
            todo += [(c[0], c[1], f"rig:{c[2]}", c[3]) for c in rig_cases(inputs)]
        counts = collections.defaultdict(collections.Counter)
        failing, review = [], []
        t0 = time.monotonic()
        for i, case in enumerate(todo):
            work = os.path.join(tmp, "work", str(i))
            result = run_case(case[3], opts.timeout, work, case[2] == "file:unreadable")
            klass = classify(case, result)
            if klass == "refused" and result["wrote"]:
                klass = "refused_wrote"
            counts[case[0]][klass] += 1
            shown = [a.replace(tmp, "$T")[:90] for a in case[3]]
            row = {"command": case[0], "option": case[1], "fault": case[2], "class": klass,
                   "status": result["status"], "argv": shown, "wall": result["wall"],
                   "err": result["err"].replace(tmp, "$T").strip()[-400:]}
            if klass not in ("refused", "accepted", "refused_other"):
                failing.append(row)
                if opts.list:
                    print(f"{klass:12s} {case[0]} {case[1]} {case[2]}: {row['err'][-200:]}", file=sys.stderr,
                          flush=True)
            elif klass in ("accepted", "refused_other"):
                review.append({k: row[k] for k in ("command", "option", "fault", "class", "status")}
                              | ({"err": row["err"][-200:]} if klass == "refused_other" else {}))
            shutil.rmtree(work, ignore_errors=True)
        lost = None
        if not opts.no_resume and (not only or "sweep" in only or "resume" in only):
            lost = lost_case(tmp, max(opts.timeout, 120))
            counts["sweep"]["lost" if not lost["same_results"] else "resumed_ok" if lost["interrupted_status"]
                            else "resume_not_interrupted"] += 1
    finally:
        unmount(tmp)
        subprocess.run(["chmod", "-R", "u+rwx", tmp], capture_output=True)
        shutil.rmtree(tmp, ignore_errors=True)
    total = collections.Counter()
    for c in counts.values():
        total.update(c)
    doc = {"command": "python benchmarks/fault_battery.py " + " ".join(argv if argv is not None else sys.argv[1:]),
           "code": CODE, "git": subprocess.run(["git", "-C", CODE, "describe", "--always", "--dirty"],
                                               capture_output=True, text=True).stdout.strip() or None,
           "cases": len(todo), "wall_s": round(time.monotonic() - t0, 1), "timeout_s": opts.timeout,
           "mounts": sorted(k for k in places if k in ("readonly", "full")),
           "total": dict(total), "per_command": {k: dict(v) for k, v in counts.items()},
           "failing": failing, "accepted_for_review": review, "resume": lost}
    text = json.dumps(doc, indent=1)
    print(text)
    if opts.out:                      # not benchjson.emit: it imports this checkout's hubbeam_ctrl, not --code's
        with open(opts.out, "w") as fh:
            fh.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
