"""Issue 39 item 4: the rig's uncertainty set and the robust certificate travel into the plant FMU.

The parameters the set moves carry their range over it as FMI ``min``/``max`` (read back by FMPy,
checked against the toolbox's own parameter vector at the set's ends); a certificate's verdict,
worst radius and worst plant are in ``<VendorAnnotations><Tool name="hubbeam_ctrl">`` exactly as
``hubbeam certify --json`` printed them, and in one sentence of the description (the sentence of the
generated C header); a certificate over another set is refused in one line.

The description checks need no C compiler: those FMUs hold their sources alone (``CC`` names none).
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
import zipfile

import pytest

from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.jsonio import strict_json
from hubbeam_ctrl.plant.models import build_model
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.plant.rig import Rig, load_rig, rig_to_toml
from hubbeam_ctrl.plant.robust_certificate import certificate_text
from hubbeam_ctrl.plant.uncertainty import Uncertainty
from hubbeam_ctrl.sim.hardware import Hardware

fmpy = pytest.importorskip("fmpy", reason="FMPy is not installed (pip install 'hubbeam-ctrl[fmu]')")
from fmpy.validation import validate_fmu  # noqa: E402

from hubbeam_ctrl.fmu import build_fmu  # noqa: E402

#: servo_link's set: every kind of parameter the FMU holds (beam, damping, friction, motor), and the delay it does not.
SERVO_SET = Uncertainty.from_table({"m_t": (0.0, 0.03), "E": (185e9, 200e9), "J_h": (2.0e-3, 2.2e-3),
                                    "damping": (0.02, 0.05), "viscous": (3e-3, 5e-3), "coulomb": (8e-3, 12e-3),
                                    "k_t": (7.5e-3, 7.8e-3), "delay": (0.3, 0.7)})
#: Table 1's beam (0.1 kg at the tip) over a payload range: a certificate in a second.
TABLE1_SET = Uncertainty.from_table({"m_t": (0.05, 0.15)})


@pytest.fixture(autouse=True)
def _no_compiler(tmp_path, monkeypatch):
    monkeypatch.setenv("CC", str(tmp_path / "no-compiler"))


def _servo() -> Rig:
    rig = load_rig("servo_link")
    return rig.replace(beam=rig.beam.replace(n_axial=2, n_transverse=3), uncertainty=SERVO_SET)


def _xml(path) -> ET.Element:
    with zipfile.ZipFile(path) as z:
        return ET.fromstring(z.read("modelDescription.xml"))


def _real(md) -> dict:
    return {v.name: v for v in md.modelVariables if v.type == "Real"}


@pytest.fixture(scope="module")
def table1_certificate():
    """LQG on Table 1 (2 design modes) certified over 0.05-0.15 kg: certify's --json document."""
    from controllers import LQG, DesignModel
    from hubbeam_ctrl.study.worst_case import certify_set
    wc = certify_set(LQG(DesignModel.build(Params(), 0.0, 0.01, 2)), Rig(beam=Params()), TABLE1_SET,
                     plant_modes=2, margins=False)
    doc = {"set": TABLE1_SET.to_table(), "controllers": {"lqg": {"certificate": wc.metrics()}}}
    return json.loads(strict_json(doc))


def test_the_set_is_the_parameters_min_max(tmp_path):
    """servo_link with an [uncertainty] table: FMPy reads (and validates) the model description; each
    parameter the set moves has its range as min/max, equal to the toolbox's values at the set's ends,
    the start (the rig's own value) inside; parameters the set leaves alone have none."""
    rig = _servo()
    info = build_fmu(rig, "foam", tmp_path / "servo.fmu")
    assert info.binary is None and validate_fmu(str(info.path)) == []
    md = fmpy.read_model_description(str(info.path), validate=True)
    real = _real(md)
    ranged = {n: (float(v.min), float(v.max)) for n, v in real.items() if v.min is not None}
    assert ranged == info.ranges and len(ranged) > 20
    for name, (lo, hi) in ranged.items():
        assert lo <= float(real[name].start) <= hi and lo < hi, name
    assert ranged["p.J_h"] == (2.0e-3, 2.2e-3)
    assert ranged["hw.viscous"] == (3e-3, 5e-3) and ranged["hw.coulomb"] == (8e-3, 12e-3)
    k_t = [Hardware.from_rig(SERVO_SET.apply(rig, {"k_t": k})).values()[2] for k in (7.5e-3, 7.8e-3)]
    assert ranged["hw.k_t"] == tuple(k_t)                  # k_t times the motor's efficiency

    def p(values, key):
        plant = build_model("foam", SERVO_SET.apply(rig, values).plant_params)
        return plant.p[[k for k, (name, _) in enumerate(_layout(plant)) if name == key][0]]
    assert ranged["p.J"] == (p({"m_t": 0.0}, "J"), p({"m_t": 0.03}, "J"))             # beam + payload inertia
    assert ranged["p.K2[1,1]"] == pytest.approx((p({"E": 185e9}, "K2[1,1]"), p({"E": 200e9}, "K2[1,1]")), rel=1e-15)
    for untouched in ("p.f2_tip[1]", "hw.V_max", "hw.N", "sensors.angle_bias", "x0.q.theta", "u"):
        assert real[untouched].min is None and real[untouched].max is None, untouched
    assert md.description.endswith("Uncertainty set m_t 0-0.03 kg, E 1.85e+11-2e+11 Pa, J_h 0.002-0.0022 kg m^2, "
                                   "damping 0.02-0.05, viscous 0.003-0.005 N m s/rad, coulomb 0.008-0.012 N m, "
                                   f"k_t 0.0075-0.0078 N m/A, delay 0.3-0.7 ({len(ranged)} parameters carry their "
                                   "range over it as min/max; delay moving none of them).")
    ranges = _xml(info.path).findall("VendorAnnotations/Tool[@name='hubbeam_ctrl']/Robustness/UncertaintySet/Range")
    assert {r.get("name"): [float(r.get("lo")), float(r.get("hi"))] for r in ranges} == SERVO_SET.to_table()
    assert [r.get("movesParameters") for r in ranges].count("false") == 1          # the delay


def _layout(plant):
    """``(name, None)`` per entry of the parameter vector, named as the FMU names them (``K2[1,1]``)."""
    out = []
    for key, (r, c) in plant.parametric.layout:
        for j in range(c):
            for i in range(r):
                out.append((key + ("" if r * c == 1 else f"[{i + 1}]" if c == 1 else f"[{i + 1},{j + 1}]"), None))
    return out


def test_the_certificate_travels_exactly(tmp_path, table1_certificate):
    """certify's JSON into the FMU: every number of the certificate reads back from the vendor annotation
    equal to the JSON's (not rounded), the worst plant too; the description's sentence is the C header's."""
    from hubbeam_ctrl.deploy.codegen import certificate_comment
    cert_file = tmp_path / "cert.json"
    cert_file.write_text(json.dumps(table1_certificate))
    rig = Rig(beam=Params(n_axial=2, n_transverse=3), uncertainty=TABLE1_SET)
    info = build_fmu(rig, "foam", tmp_path / "t1.fmu", certificate=cert_file)
    cert = table1_certificate["controllers"]["lqg"]["certificate"]
    root = _xml(info.path)
    (el,) = root.findall("VendorAnnotations/Tool[@name='hubbeam_ctrl']/Robustness/Certificate")
    assert el.get("controller") == "lqg" and el.get("verdict") == cert["robust_verdict"]
    assert float(el.get("radius")) == cert["robust_radius"]
    assert int(el.get("evaluations")) == cert["robust_evaluations"]
    for key, value in cert.items():
        short = key.removeprefix("robust_")
        if isinstance(value, float):
            assert float(el.get(short)) == value, key
        elif isinstance(value, (int, str)) and not isinstance(value, bool):
            assert el.get(short) == str(value), key
    assert {w.get("name"): float(w.get("value")) for w in el.findall("Worst")} == cert["robust_worst"]
    md = fmpy.read_model_description(str(info.path), validate=True)
    verdict, worst = certificate_text(cert)
    assert md.description.endswith(f"lqg: {verdict} {worst}") and "\n" not in md.description
    assert certificate_comment(cert) == f"/* {verdict}\n   {worst} */\n\n"
    # the same from the dict GeneratedCode.certificate holds (no controller name: "controller")
    other = build_fmu(rig, "foam", tmp_path / "t2.fmu", certificate=cert)
    (el2,) = _xml(other.path).findall("VendorAnnotations/Tool/Robustness/Certificate")
    assert el2.get("controller") == "controller" and el2.get("radius") == el.get("radius")


def test_cli_writes_the_certificate_and_refuses_another_set_in_one_line(tmp_path, capsys, table1_certificate):
    """``hubbeam fmu --rig RIG --certificate CERT.json``: exit 0 and the annotation; a certificate over
    another set, or on a rig without one, or not a certificate: exit 2, one line naming --certificate,
    nothing written."""
    rig_file = tmp_path / "t1.toml"
    rig_file.write_text(rig_to_toml(Rig(beam=Params(n_axial=2, n_transverse=3), uncertainty=TABLE1_SET)))
    good = tmp_path / "cert.json"
    good.write_text(json.dumps(table1_certificate))
    assert main(["fmu", "--rig", str(rig_file), "--certificate", str(good), "--out", str(tmp_path / "ok.fmu"),
                 "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    cert = table1_certificate["controllers"]["lqg"]["certificate"]
    assert summary["certificate"] == {"lqg": {"robust_verdict": cert["robust_verdict"],
                                              "robust_radius": cert["robust_radius"]}}
    assert summary["parameters_with_set_range"] > 0
    other = json.loads(json.dumps(table1_certificate))
    other["set"]["m_t"] = [0.05, 0.2]
    other["controllers"]["lqg"]["certificate"]["robust_set"]["m_t"] = [0.05, 0.2]
    bad = tmp_path / "other.json"
    bad.write_text(json.dumps(other))
    not_cert = tmp_path / "not.json"
    not_cert.write_text('{"x": 1}')
    for rig, cert_file, message in (
            (str(rig_file), bad, "--certificate: the certificate's set (m_t 0.05-0.2 kg) is not the rig's "
                                 "(m_t 0.05-0.15 kg)"),
            ("servo_link", good, "is not the rig's (no [uncertainty] table)"),
            (str(rig_file), not_cert, "--certificate must be hubbeam certify's JSON")):
        out = tmp_path / "refused.fmu"
        assert main(["fmu", "--rig", rig, "--certificate", str(cert_file), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err and "Traceback" not in err, err
        assert not out.exists()
    with pytest.raises(ParameterError, match=r"^certificate: the certificate's set \(m_t 0.05-0.2 kg\)"):
        build_fmu(Rig(beam=Params(n_axial=2, n_transverse=3), uncertainty=TABLE1_SET), "foam",
                  tmp_path / "x.fmu", certificate=other)
    assert not (tmp_path / "x.fmu").exists()


def test_a_set_that_leaves_the_rig_out_is_refused(tmp_path):
    """The FMU's parameters start at the rig's values: a set without the rig's own payload would give
    starts outside min/max, and is refused in one line naming the parameter."""
    rig = Rig(beam=Params(n_axial=2, n_transverse=3), uncertainty=Uncertainty.from_table({"m_t": (0.2, 0.5)}))
    with pytest.raises(ParameterError, match=r"^rig: its own m_t = 0.1 kg is outside its \[uncertainty\] range "
                                             r"\[0.2, 0.5\]"):
        build_fmu(rig, "foam", tmp_path / "x.fmu")
    assert not (tmp_path / "x.fmu").exists()


def test_a_rig_without_a_set_is_unchanged(tmp_path):
    """No [uncertainty] table: no min/max, no annotation, the description as before."""
    info = build_fmu(Params(n_axial=2, n_transverse=3), "foam", tmp_path / "p.fmu")
    root = _xml(info.path)
    assert info.ranges == {} and root.find("VendorAnnotations") is None
    assert not any("min" in e.attrib for e in root.iter("Real"))
    assert root.get("description").endswith("steps per sample (hubbeam-ctrl)")


@pytest.mark.slow
def test_certify_json_into_the_fmu_end_to_end(tmp_path, capsys, monkeypatch):
    """``hubbeam certify lqr --rig RIG --json`` on servo_link with a set (its stdout saved as the file),
    then ``hubbeam fmu --rig RIG --certificate`` it: the radius and the worst plant read back exactly,
    and the compiled FMU runs in FMPy with its parameters at the ends of their ranges."""
    rig_file = tmp_path / "servo_set.toml"
    rig = _servo().replace(uncertainty=Uncertainty.from_table({"m_t": (0.0, 0.03), "E": (185e9, 200e9),
                                                                "damping": (0.02, 0.05)}))
    rig_file.write_text(rig_to_toml(rig))
    assert main(["certify", "lqr", "--rig", str(rig_file), "--check", "none", "--json",
                 "--out", str(tmp_path / "cert")]) == 0
    printed = capsys.readouterr().out
    (tmp_path / "cert.json").write_text(printed)
    doc = json.loads(printed)
    monkeypatch.delenv("CC")
    from hubbeam_ctrl.core.compiled import CompileError, find_compiler
    try:
        find_compiler()
    except CompileError as exc:
        pytest.skip(f"the FMU's binary needs a C compiler: {exc}")
    out = tmp_path / "servo.fmu"
    assert main(["fmu", "--rig", str(rig_file), "--certificate", str(tmp_path / "cert.json"), "--out", str(out)]) == 0
    capsys.readouterr()
    (el,) = _xml(out).findall("VendorAnnotations/Tool[@name='hubbeam_ctrl']/Robustness/Certificate")
    cert = doc["controllers"]["lqr"]["certificate"]
    assert el.get("verdict") == "certified" and float(el.get("radius")) == cert["robust_radius"]
    assert {w.get("name"): float(w.get("value")) for w in el.findall("Worst")} == cert["robust_worst"]
    md = fmpy.read_model_description(str(out), validate=True)
    ends = {v.name: float(v.max) for v in md.modelVariables if v.type == "Real" and v.max is not None}
    res = fmpy.simulate_fmu(str(out), stop_time=0.2, output_interval=rig.timing.dt, start_values=ends,
                            output=["v_tip"])
    assert len(res) == 201 and all(abs(x) < 1.0 for x in res["v_tip"])


@pytest.mark.slow
def test_the_corners_give_the_range_of_a_grid():
    """The ranges are the hull over the set's corners (65 positions when l is uncertain): on servo_link
    (2 + 3 modes) that equals the hull over a 5-point grid per parameter of m_t, E, J_h and damping, and
    the l positions' hull is within 1e-3 of a 257-position scan's, relative to the parameter's largest
    value (measured 2e-4). 15 s."""
    import itertools

    import numpy as np

    from hubbeam_ctrl.fmu.build import _starts_at
    from hubbeam_ctrl.fmu.description import set_ranges
    from hubbeam_ctrl.sim.stepper import StepperSettings
    starts_at = _starts_at("foam", True, 2, (0.0,), StepperSettings(dt=1e-3, substeps=2))
    rig = _servo()

    def hull(u, axes):
        bare = rig.replace(uncertainty=Uncertainty())
        samples = [starts_at(u.apply(bare, dict(zip(u.names, v)))) for v in itertools.product(*axes)]
        return {n: (min(s[n] for s in samples), max(s[n] for s in samples)) for n in samples[0]}

    u = Uncertainty.from_table({"m_t": (0.0, 0.03), "E": (185e9, 200e9), "J_h": (2.0e-3, 2.2e-3),
                                "damping": (0.02, 0.05)})
    ranges = set_ranges(rig.replace(uncertainty=u), starts_at).ranges
    grid = hull(u, [np.linspace(r.lo, r.hi, 5) for r in u.ranges])
    for name, (lo, hi) in ranges.items():
        scale = max(abs(grid[name][0]), abs(grid[name][1]))
        assert abs(lo - grid[name][0]) <= 1e-14 * scale and abs(hi - grid[name][1]) <= 1e-14 * scale, name
    assert {n for n, (lo, hi) in grid.items() if hi > lo} == set(ranges)
    u = Uncertainty.from_table({"m_t": (0.0, 0.03), "l": (0.2, 0.381)})
    ranges = set_ranges(rig.replace(uncertainty=u), starts_at).ranges
    scan = hull(u, [(0.0, 0.03), np.linspace(0.2, 0.381, 257)])
    worst = max(max(abs(lo - scan[n][0]), abs(hi - scan[n][1])) / max(abs(scan[n][0]), abs(scan[n][1]))
                for n, (lo, hi) in ranges.items())
    print(f"l: 65 positions vs 257, largest relative gap {worst:.2e}")
    assert worst <= 1e-3


def test_what_the_set_moves_is_said(tmp_path):
    """On Table 1's beam with an ideal torque drive the FMU has no friction parameters: a viscous range
    moves none of them, said in the description and the annotation; the tip position moves the mass
    moments even though the payload's range starts at 0 kg (where it moves nothing)."""
    u = Uncertainty.from_table({"m_t": (0.0, 0.2), "l": (7.0, 8.0), "viscous": (0.0, 0.5)})
    rig = Rig(beam=Params(n_axial=2, n_transverse=3, l=7.5), uncertainty=u)
    info = build_fmu(rig, "foam", tmp_path / "t.fmu")
    root = _xml(info.path)
    moves = {r.get("name"): r.get("movesParameters") for r in root.iter("Range")}
    assert moves == {"m_t": "true", "l": "true", "viscous": "false"}
    assert "as min/max; viscous moving none of them)." in root.get("description")
    assert "p.J" in info.ranges and not any(n.startswith("hw.") for n in info.ranges)
