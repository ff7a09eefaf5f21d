"""Every option of ``hubbeam compare`` acts or is refused, in each of its modes (issue 41).

The mode x option table is read from the argparse parser itself: an option added to
``compare`` without a sample value here fails :func:`test_every_option_acts_or_is_refused`,
so none can be accepted and silently dropped. The walk runs at the level where options become
values (``hubbeam_ctrl.cli.compare.COMMAND.plan``: the keyword arguments that both
:func:`~hubbeam_ctrl.study.compare.compare` and, with ``--payload-range``,
:func:`~hubbeam_ctrl.study.payload.payload_comparison` take); a few real runs check that the
payload path acts on what it is given.
"""

import json

import pytest

from hubbeam_ctrl.cli.compare import COMMAND as COMPARE
from hubbeam_ctrl.cli.main import build_parser, main
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.study.compare_values import CompareSettings, ScenarioChoice

#: The modes of ``compare``: the options that select each.
MODES = {"slew": [], "payload range": ["--payload-range", "0,0.5"],
         "learn payload": ["--payload-range", "0,0.5", "--learn-payload"], "rig": ["--rig", "servo_link"],
         "spin-up": ["--scenario", "spinup"], "shaping": ["--shaping", "zvd"], "schedule": ["--schedule", "3"]}

#: A valid value other than the default for every option that takes one (choices are picked
#: from the parser; ``{mode: value}`` where a mode needs its own).
SAMPLES = {"--params": "DAMPED", "--tip-mass": "0.2", "--tip-position": {"rig": "0.3", None: "7.5"}, "--n-modes": "4",
           "--plant-params": "DAMPED", "--plant-tip-mass": "0.2", "--design-modes": "3", "--plant-modes": "12",
           "--range-limit": "0.2", "--controllers": "openloop,lqr,mpc", "--tau-max": {"rig": "1", None: "150"},
           "--slew-angle": "1", "--tf": {"rig": "1", None: "8"}, "--t-end": {"rig": "5", None: "40"},
           "--wf": "2", "--dt": "0.005", "--rig": "servo_link", "--horizon": "30", "--schedule": "2",
           "--out": "OTHER", "--payload-range": "0,0.4", "--max-wall": "100", "--reference": "planned",
           "--limit": "optimal", "--plant": "cfoam", "--check-plant": "cfoam", "--solver": "osqp",
           "--settle-angle": "0.05deg", "--settle-tip": "0.5mm"}

#: Handled by ``hubbeam``'s entry point for every command (:func:`hubbeam_ctrl.cli.main._run`).
ENTRY_POINT = {"-h", "--help", "--verbose"}


def _compare_parser():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    return parser, sub.choices["compare"]


def _option_args(action, mode, files, base):
    """The command-line words that give ``action`` a value other than the default (and the mode's)."""
    option = max(action.option_strings, key=len)
    if action.nargs == 0:
        return [option]
    sample = SAMPLES.get(option)
    if isinstance(sample, dict):
        sample = sample.get(mode, sample[None])
    if sample is None and action.choices is not None:
        taken = {action.default, base[base.index(option) + 1] if option in base else None}
        sample = next(c for c in action.choices if c not in taken and c != "ancf")   # ancf: needs Exudyn
    assert sample is not None, f"{option} has no sample value: add one to SAMPLES (it must act or be refused)"
    return [option, files.get(sample, sample)]


def _plan(parser, words):
    return COMPARE.plan(parser.parse_args(["compare", *words]))


@pytest.fixture
def files(tmp_path):
    damped = tmp_path / "damped.toml"
    damped.write_text("damping_ratio = 5e-4\n")
    return {"DAMPED": str(damped), "OUT": str(tmp_path / "out"), "OTHER": str(tmp_path / "other")}


@pytest.mark.parametrize("mode", list(MODES))
def test_every_option_acts_or_is_refused(mode, files):
    parser, compare = _compare_parser()
    base = MODES[mode] + ["--out", files["OUT"]]
    reference = _plan(parser, base)
    walked = 0
    for action in compare._actions:
        if not action.option_strings or set(action.option_strings) & ENTRY_POINT:
            continue
        option = max(action.option_strings, key=len)
        if option in base:                   # the options that select the mode act by selecting it
            continue
        words = _option_args(action, mode, files, base)
        try:
            plan = _plan(parser, base + words)
        except ParameterError as exc:
            text = str(exc)
            assert "\n" not in text and option in text, (mode, option, text)
            others = [w for w in text.replace("(", " ").replace(",", " ").split() if w.startswith("--")]
            assert set(others) - {option}, f"{mode}: refusing {option} must name what it conflicts with: {text}"
            continue
        assert plan != reference, f"{mode}: {' '.join(words)} accepted and ignored"
        walked += 1
    assert walked >= 20, walked              # most options act in every mode


def test_the_payload_path_refuses_in_one_line(files):
    parser, _ = _compare_parser()
    base = ["--payload-range", "0,0.5", "--out", files["OUT"]]
    cases = {("--plant-tip-mass", "0.2"): "--plant-tip-mass does not apply with --payload-range",
             ("--rig", "servo_link"): "--rig does not apply with --payload-range",
             ("--learn-payload", "--shaping", "zv"): "--shaping does not apply with --learn-payload",
             ("--learn-payload", "--schedule", "2"): "--schedule does not apply with --learn-payload"}
    for words, message in cases.items():
        with pytest.raises(ParameterError, match=message):
            _plan(parser, base + list(words))
    for words in (["--scenario", "spinup", "--reference", "planned"], ["--scenario", "spinup", "--limit", "optimal"]):
        with pytest.raises(ParameterError, match=f"{words[2]} {words[3]} applies to --scenario slew only"):
            _plan(parser, ["--out", files["OUT"]] + words)


def test_the_payload_path_takes_the_plain_compare_values(files):
    """The payload plan holds the plain plan's values, and those of the range."""
    parser, _ = _compare_parser()
    words = ["--plant-params", files["DAMPED"], "--design-modes", "4", "--t-end", "16", "--out", files["OUT"]]
    plain = _plan(parser, words).options
    payload = _plan(parser, words + ["--payload-range", "0,0.5"]).options
    assert payload.pop("payload_range") == (0.0, 0.5)
    assert payload == plain
    assert plain["plant_params"].damping_ratio == 5e-4 and plain["design_modes"] == 4


def _payload_rows(out, extra, capsys):
    assert main(["compare", "--payload-range", "0,0.5", "--controllers", "openloop,lqr", "--t-end", "16",
                 "--out", str(out), "--json", *extra]) == 0
    capsys.readouterr()
    doc = json.loads((out / "payload.json").read_text())
    return {(r["payload_kg"], r["controller"]): r for r in doc["rows"]}, (out / "payload_report.md").read_text()


@pytest.mark.slow
def test_payload_range_runs_on_the_damped_plant(tmp_path, files, capsys, fast_backend):
    """Issue 41's target: ``--payload-range 0,0.5 --plant-params`` with 0.05 % damping runs on the
    damped plant (the report says so) and the certificate's radius differs from the undamped run's:
    LQR's sampled loop on the undamped 10-mode plant has radius 1.00001-1.00097 (its unmodelled
    modes ring up: "unstable"); with damping_ratio 5e-4 every payload's is below 1 (0.9986-0.9989).
    (The runs stop at 16 s: a residual window of 1 s, too short to judge the damped runs' envelopes;
    the certificate judges both.)"""
    damped, report = _payload_rows(tmp_path / "damped", ["--plant-params", files["DAMPED"]], capsys)
    undamped, plain_report = _payload_rows(tmp_path / "undamped", [], capsys)
    assert "structural damping ratio 0.0005" in report and "damping_ratio, m_t differ from the design's" in report
    assert "structural damping ratio 0." in plain_report
    for m in (0.0, 0.1, 0.5):
        rd, ru = damped[(m, "lqr")]["loop_spectral_radius"], undamped[(m, "lqr")]["loop_spectral_radius"]
        assert ru > 1.0 > rd, (m, rd, ru)
        assert undamped[(m, "lqr")]["verdict"] == "unstable"


def test_compare_derives_t_end_from_a_long_task(tmp_path, capsys, fast_backend):
    """Issue 36 item 9: a 40 s slew without --t-end is accepted (it was refused, "got 30 s", because
    the scenario was first built with 30 s) and runs the task's own t_end: 3 tf = 120 s, the longer
    of 3 tf and the residual window (tf + tf/2 + six periods of the 0.46 Hz first mode: 73 s)."""
    from hubbeam_ctrl.study.compare import compare
    from hubbeam_ctrl.study.yardstick import task_t_end
    assert main(["compare", "--tf", "40", "--controllers", "openloop", "--out", str(tmp_path / "o"), "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)
    assert row["completed"] and row["limit_s"] == pytest.approx(2 * (12.807 * 16 * 248.5 / 200) ** 0.5, rel=1e-3)
    c = compare(None, "slew", "openloop", CompareSettings(scenario=ScenarioChoice(t_f=40.0)))
    assert c.scenario.t_end == task_t_end(c.scenario) == pytest.approx(120.0)
    assert c.results["openloop"].t[-1] == pytest.approx(120.0)
    short = compare(None, "slew", "openloop",
                    CompareSettings(scenario=ScenarioChoice(t_f=5.0))).scenario    # the window is the longer: 20.55 s
    assert short.t_end == task_t_end(short) == pytest.approx(5.0 + 2.5 + 6 * 2.175, abs=0.01)


#: ``hubbeam design`` and ``codegen``: a valid value other than the default for each option
#: (choices: from the parser).
RUN_SAMPLES = {"--params": "DAMPED", "--schedule": "3", "--tip-mass": "0.2", "--tip-position": "7.5", "--n-modes": "4",
               "--slew-angle": "1", "--tf": "8", "--wf": "2", "--payload-range": "0,0.5", "--dt": "0.005",
               "--rig": "servo_link", "--design-modes": "1", "--tau-max": "150", "--controller": "pd",
               "--duration": "5", "--amplitude": "0.5", "--band": "2:40", "--modes": "1", "--max-tip": "0.01",
               "--max-hub": "0.05", "--seed": "3"}


def _run(command, words, capsys, out):
    """``(exit status, printed, saved, stderr)`` of a command writing to ``out`` (a file or a
    folder), the path replaced in what it printed and saved (MANIFEST.json left out: its hashes)."""
    from pathlib import Path
    try:
        status = main([command, *words])
    except SystemExit as exc:                 # argparse
        status = exc.code
    printed = capsys.readouterr()
    out = Path(out)
    files = sorted(out.iterdir()) if out.is_dir() else [out] if out.exists() else []
    saved = {f.name if out.is_dir() else "out": _content(f).replace(str(out).encode(), b"OUT")
             for f in files if f.name != "MANIFEST.json"}
    return status, printed.out.replace(str(out), "OUT"), saved, printed.err


def _content(path) -> bytes:
    """A file's bytes; an FMU's (a zip) as its members' bytes without the zip's dates and the
    model description's ``generationDateAndTime``."""
    import re
    import zipfile
    if path.suffix != ".fmu":
        return path.read_bytes()
    with zipfile.ZipFile(path) as z:
        text = b"".join(n.encode() + b"\0" + z.read(n) for n in sorted(z.namelist()))
    return re.sub(rb'generationDateAndTime="[^"]*"', b"", text)


def _walk_runs(command, base, out_name, tmp_path, files, capsys, skip=("--controller",), samples=None):
    """Run ``command`` with ``base`` and with each of its parser's options added: each must change what
    is printed or saved, or exit 2 in one line naming it and what it conflicts with. ``samples``: values
    of this walk's own (over :data:`RUN_SAMPLES`). Returns how many options were walked."""
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    runs = iter(range(10 ** 6))
    out = lambda: tmp_path / f"{next(runs)}{out_name}"      # noqa: E731  (a fresh output each run)
    first = out()
    reference = _run(command, base + ["--out", str(first)], capsys, first)
    assert reference[0] == 0, reference[3]
    walked = 0
    for action in sub.choices[command]._actions:
        option = max(action.option_strings, key=len, default="")
        if not option or option in ENTRY_POINT or option in skip:
            continue
        target = out()
        if option == "--out":                 # acts by writing there
            assert _run(command, base + ["--out", str(target)], capsys, target)[2] == reference[2]
            walked += 1
            continue
        if option == "--force":               # acts by writing into a non-empty folder (over a file)
            assert _run(command, base + ["--out", str(first)], capsys, first)[0] == 2
            assert _run(command, base + ["--out", str(first), "--force"], capsys, first)[0] == 0
            walked += 1
            continue
        if action.nargs == 0:
            words = [option]
        elif action.choices is not None:
            taken = {action.default, base[base.index(option) + 1] if option in base else None}
            words = [option, next(c for c in action.choices if c not in taken)]
        else:
            sample = {**RUN_SAMPLES, **(samples or {})}.get(option)
            assert sample is not None, f"{command} {option} has no sample value: add one to RUN_SAMPLES"
            words = [option, files.get(sample, sample)]
        walked += 1
        status, printed, saved, err = _run(command, base + words + ["--out", str(target)], capsys, target)
        if status != 0:
            assert status == 2 and err.count("\n") == 1 and option in err, (command, option, err)
            assert {w for w in err.replace("(", " ").split() if w.startswith("--")} - {option}, err
            continue
        assert (printed, saved) != reference[1:3], f"{command} {' '.join(base + words)} accepted and ignored"
    return walked


@pytest.mark.slow
def test_every_design_option_acts_or_is_refused(tmp_path, files, capsys, fast_backend):
    """``hubbeam design --controller lqr`` (the slew): each option changes what is saved or printed,
    or is refused; --payload-range (the one slow option, 8 s) designs LQR for the range, and with PD
    it is refused (it was silently ignored)."""
    _walk_runs("design", ["--controller", "lqr", "--n-modes", "2"], ".json", tmp_path, files, capsys)
    status, _, _, err = _run("design", ["--controller", "pd", "--payload-range", "0,0.5", "--out",
                                        str(tmp_path / "pd.json")], capsys, tmp_path / "pd.json")
    assert status == 2 and "--payload-range does not apply to --controller pd (only to lqr, lqg)" in err


@pytest.mark.slow
@pytest.mark.parametrize("controller", ["lqr", "zvd"])
def test_every_codegen_option_acts_or_is_refused(controller, tmp_path, files, capsys):
    """``hubbeam codegen`` for a feedback controller and an input shaper: each option changes the
    generated code or what is printed, or is refused."""
    _walk_runs("codegen", ["--controller", controller, "--n-modes", "2"], "_c", tmp_path, files, capsys)


#: ``hubbeam optimal``: its modes and a value other than the default for each option.
OPTIMAL_MODES = {"time-optimal": [], "min-vibration": ["--duration", "3"], "rig": ["--rig", "servo_link"]}
OPTIMAL_SAMPLES = {"--params": "DAMPED", "--tip-mass": "0.2", "--tip-position": {"rig": "0.3", None: "7.5"},
                   "--n-modes": "4", "--rig": "servo_link", "--tolerance": "0.002", "--duration": "4",
                   "--intervals": "24"}


def _walk_plans(command, base, samples, files, mode=None):
    """Walk ``command``'s options at the level where they become the run's values: its ``COMMAND.plan``
    (:class:`~hubbeam_ctrl.cli.args.Command`) of ``base`` and of ``base`` with each option added (``samples``: option ->
    value, or ``{mode: value, None: value}``) must differ, or the option is refused in one line naming
    it and what it conflicts with. The options in ``base`` select the mode and are not walked.
    Returns how many options were walked."""
    import importlib
    plan_of = importlib.import_module(f"hubbeam_ctrl.cli.{command}").COMMAND.plan
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    words_of = lambda w: [files.get(x, x) for x in w]        # noqa: E731
    reference = plan_of(parser.parse_args([command, *words_of(base)]))
    walked = 0
    for action in sub.choices[command]._actions:
        option = max(action.option_strings, key=len, default="")
        if not option or option in ENTRY_POINT or option in base:
            continue
        sample = samples.get(option)
        sample = sample.get(mode, sample[None]) if isinstance(sample, dict) else sample
        if sample is None and action.choices is not None:
            sample = next(c for c in action.choices if c != action.default)
        assert action.nargs == 0 or sample is not None, f"{command} {option} has no sample value"
        words = [option] if action.nargs == 0 else [option, sample]
        walked += 1
        try:
            plan = plan_of(parser.parse_args([command, *words_of(base + words)]))
        except ParameterError as exc:
            text = str(exc)
            assert "\n" not in text and option in text, (mode, option, text)
            named = {w for w in text.replace("(", " ").split() if w.startswith("--") or w.isupper()}
            assert named - {option}, text          # the option or the argument (RECORD) it conflicts with
            continue
        assert plan != reference, f"{command} {mode}: {' '.join(words)} accepted and ignored"
    return walked


@pytest.mark.parametrize("mode", list(OPTIMAL_MODES))
def test_every_optimal_option_acts_or_is_refused(mode, files):
    """``hubbeam optimal``'s options, walked at the level where they become the run's values
    (its ``COMMAND.plan``), in each of its modes."""
    walked = _walk_plans("optimal", ["--slew-angle", "1", *OPTIMAL_MODES[mode]], OPTIMAL_SAMPLES, files, mode)
    assert walked == 10 - len(OPTIMAL_MODES[mode]) // 2, walked


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["chirp", "prbs", "multisine", "step"])
def test_every_excite_option_acts_or_is_refused(kind, tmp_path, files, capsys):
    """``hubbeam excite`` on ``servo_link``, each kind of record: each option changes the record or
    what is printed, or is refused."""
    _walk_runs("excite", ["--rig", "servo_link", "--kind", kind], ".csv", tmp_path, files, capsys,
               skip=("--kind", "--rig"))


def test_fmu_refuses_spin_with_substeps(tmp_path, capsys):
    """``--spin`` only sets the modal analysis of the substep rule: with ``--substeps`` it was ignored."""
    out = tmp_path / "p.fmu"
    assert main(["fmu", "--substeps", "3", "--spin", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--spin does not apply with --substeps" in err and not out.exists()


@pytest.mark.parametrize("words, message", [
    (["--scheduler-timeout", "1"], "--scheduler-timeout applies with --scheduler only"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:9"],
     "--workers does not apply with --scheduler (the cluster's workers run the cases)")])
@pytest.mark.parametrize("command", ["sweep", "tune"])
def test_engine_options_that_do_not_apply_are_refused(command, words, message, tmp_path, capsys):
    """sweep and tune: a scheduler timeout without a scheduler, local workers with a cluster (both
    were accepted and ignored)."""
    spec = tmp_path / "s.toml"
    spec.write_text('[study]\ncontrollers = ["openloop", "lqr"]\nt_f = 1.0\nt_end = 6.5\n[params]\n'
                    'n_axial = 2\nn_transverse = 2\n[grid]\nm_t = [0.0, 0.2]\n')
    extra = ["--controller", "lqr"] if command == "tune" else []
    assert main([command, str(spec), *extra, "--out", str(tmp_path / "o"), *words]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


@pytest.mark.parametrize("words", [["--validate", "v.csv"], ["--sensors", "theta"], ["--plant-modes", "3"],
                                   ["--max-wall", "5"]])
def test_identify_modal_table_refuses_record_options(words, tmp_path, capsys):
    """``identify --modal-table`` fits frequencies by modal analysis: the options of a fit to
    records (validation records, sensors, the simulated plant's modes, the fit's wall limit) were
    accepted and ignored."""
    table = tmp_path / "t.csv"
    table.write_text("spin [rad/s],m_t [kg],mode [-],frequency [Hz],damping [-]\n0,0,1,20,0.01\n")
    assert main(["identify", "--modal-table", str(table), "--rig", "servo_link", "--fit", "E",
                 "--out", str(tmp_path / "o"), *words]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{words[0]} does not apply with --modal-table (it fits records)" in err



#: ``hubbeam fmu``: its modes (the options that select each) and the values of its own. "set": servo_link
#: with an [uncertainty] table (FMU_SET), where --certificate (certify's JSON over that set) acts; on the
#: other modes it is refused (their rigs have no set).
FMU_MODES = {"model": ["--n-modes", "2"], "substeps": ["--n-modes", "2", "--substeps", "3"],
             "rig": ["--n-modes", "2", "--rig", "servo_link"], "set": ["--n-modes", "2", "--rig", "SETRIG"]}
FMU_SAMPLES = {"model": {"--dt": "0.005", "--substeps": "4", "--spin": "20", "--certificate": "CERT"},
               "substeps": {"--dt": "0.005", "--substeps": "4", "--spin": "20", "--certificate": "CERT"},
               "rig": {"--dt": "0.002", "--substeps": "4", "--spin": "20", "--tip-position": "0.3",
                       "--certificate": "CERT"},
               "set": {"--dt": "0.002", "--substeps": "4", "--spin": "20", "--tip-position": "0.3",
                       "--certificate": "CERT"}}
FMU_SET = {"m_t": [0.0, 0.25], "E": [185e9, 200e9], "damping": [0.02, 0.05]}


@pytest.mark.parametrize("mode", list(FMU_MODES))
def test_every_fmu_option_acts_or_is_refused(mode, tmp_path, files, capsys, monkeypatch):
    """``hubbeam fmu`` in each of its modes: each option changes the FMU (its members, the build date
    left out) or what is printed, or is refused. Without a C compiler (``CC`` names none) the FMU holds
    its generated sources alone, which the binary is compiled from: 0.2 s a build instead of 2 s
    (tests/test_fmu.py builds and runs the binary)."""
    monkeypatch.setenv("CC", str(tmp_path / "no-compiler"))
    from hubbeam_ctrl.plant.rig import load_rig, rig_to_toml
    from hubbeam_ctrl.plant.uncertainty import Uncertainty
    (tmp_path / "set.toml").write_text(rig_to_toml(load_rig("servo_link").replace(
        uncertainty=Uncertainty.from_table(FMU_SET))))
    cert = {"robust_verdict": "certified", "robust_radius": 0.99, "robust_worst": {"m_t": 0.25, "E": 185e9,
            "damping": 0.02}, "robust_set": FMU_SET, "robust_evaluations": 10, "robust_plant_modes": 2}
    (tmp_path / "cert.json").write_text(json.dumps({"set": FMU_SET, "controllers": {"lqr": {"certificate": cert}}}))
    files = {**files, "SETRIG": str(tmp_path / "set.toml"), "CERT": str(tmp_path / "cert.json")}
    base = [files.get(w, w) for w in FMU_MODES[mode]]
    walked = _walk_runs("fmu", base, ".fmu", tmp_path, files, capsys, skip=base[2::2], samples=FMU_SAMPLES[mode])
    assert walked == 13 - len(base[2::2]), walked


#: A small study spec: a grid over the tip mass, and the same spread as a Monte Carlo sample (a spin-up:
#: checking a slew spec plans its reference, 0.7 s a plan on a loaded machine).
SPEC = ('[study]\nscenario = "spinup"\ncontrollers = ["openloop", "lqr"]\nt_f = 2.0\nw_f = 0.5\nt_end = 6.5\n'
        '[params]\nn_axial = 2\nn_transverse = 2\n')
STUDY_MODES = {"grid": SPEC + "[grid]\nm_t = [0.0, 0.2]\n",
               "monte carlo": SPEC + '[random]\nn = 2\nseed = 1\nm_t = {dist = "uniform", low = 0.0, high = 0.2}\n'}
STUDY_SAMPLES = {"--out": "OTHER", "--settings": "SETTINGS", "--plant": "cfoam", "--rig": "servo_link",
                 "--workers": "2", "--scheduler": "tcp://127.0.0.1:9", "--scheduler-timeout": "1",
                 "--objective": "0.9", "--maxiter": "3", "--popsize": "2", "--decades": "1", "--seed": "4"}


@pytest.fixture
def study(tmp_path, files):
    """``files`` with ``SPEC`` (written per mode by the test) and a settings file ``SETTINGS``."""
    (tmp_path / "settings.toml").write_text("[settings.lqr.weights]\nangle = 2.0\n")
    return {**files, "SPEC": str(tmp_path / "spec.toml"), "SETTINGS": str(tmp_path / "settings.toml")}


@pytest.mark.parametrize("command", ["sweep", "tune"])
@pytest.mark.parametrize("mode", list(STUDY_MODES))
def test_every_study_option_acts_or_is_refused(command, mode, study):
    """``hubbeam sweep`` and ``tune`` on a grid and a Monte Carlo spec: each option changes the run's
    values (their ``COMMAND.plan``: the study, the engine, the tuner's options) or is refused; the engine
    options are run for real in :func:`test_engine_options_that_do_not_apply_are_refused` and
    tests/test_sweep.py."""
    from pathlib import Path
    Path(study["SPEC"]).write_text(STUDY_MODES[mode])
    base = ["SPEC", "--out", "OUT"] + (["--controller", "lqr"] if command == "tune" else [])
    walked = _walk_plans(command, base, STUDY_SAMPLES, study, mode)
    assert walked == {"sweep": 8, "tune": 10}[command], walked


#: ``hubbeam identify``'s modes: a fit to a record on a rig or a parameter file, a modal table.
IDENTIFY_MODES = {"record, rig": ["REC", "--rig", "servo_link", "--fit", "E"],
                  "record, params": ["REC", "--params", "DAMPED", "--fit", "E"],
                  "modal table": ["--modal-table", "TABLE", "--rig", "servo_link", "--fit", "E"]}
IDENTIFY_SAMPLES = {"--modal-table": "TABLE", "--rig": "servo_link", "--params": "DAMPED", "--fit": "E,J_h",
                    "--out": "OTHER", "--validate": "REC", "--bounds": "E=1e10:1e12", "--sensors": "theta",
                    "--max-evaluations": "5", "--plant-modes": "3", "--max-wall": "100"}


@pytest.mark.parametrize("mode", list(IDENTIFY_MODES))
def test_every_identify_option_acts_or_is_refused(mode, files, tmp_path):
    """``hubbeam identify``'s options, at the level where they become the fit's values
    (its ``COMMAND.plan``), in each of its modes: ``--max-wall`` with ``--modal-table`` was accepted
    and ignored (the modal fit has no wall limit): refused."""
    (tmp_path / "t.csv").write_text("spin [rad/s],m_t [kg],mode [-],frequency [Hz],damping [-]\n0,0,1,20,0.01\n")
    (tmp_path / "r.csv").write_text("t [s],V [V],theta [rad]\n0,0,0\n0.001,1,0\n")
    paths = {**files, "TABLE": str(tmp_path / "t.csv"), "REC": str(tmp_path / "r.csv")}
    base = IDENTIFY_MODES[mode] + ["--out", "OUT"]
    walked = _walk_plans("identify", base, IDENTIFY_SAMPLES, paths, mode)
    assert walked == 13 - len(base) // 2, walked
