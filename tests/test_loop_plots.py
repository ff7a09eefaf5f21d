"""Loop plots (issue 24): the loop data against independent computations, the figure, the
report's loop figures and report.html (in headless Chromium where it is installed)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import control
import numpy as np
import pytest
from matplotlib.figure import Figure

from controllers import LQG, LQR, PD, DesignModel, LQGSettings
from controllers.analysis import FrequencyResponse, loop_margins, loop_matrices, loop_transfer
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.htmlpage import markdown_to_html
from hubbeam_ctrl.plots.loops import disk_margin_disk, plot_loop, sensitivity_peaks
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.compare_values import CompareSettings, DesignChoice, PlantChoice
from hubbeam_ctrl.study.loops import evaluation_model, loop_figure, loop_response
from hubbeam_ctrl.study.report import write_outputs
from hubbeam_ctrl.study.spillover import loop_poles


@pytest.fixture(scope="module")
def design():
    return DesignModel.build(n_modes=2)


@pytest.mark.parametrize("alpha", [0.3, 1.0, 1.7])
def test_disk_boundary_is_where_S_minus_half_is_one_over_alpha(alpha):
    c, r = disk_margin_disk(alpha)
    L = c + r * np.exp(1j * np.linspace(0, 2 * np.pi, 37))
    np.testing.assert_allclose(np.abs(1 / (1 + L) - 0.5), 1 / alpha, rtol=1e-12)
    a = alpha / 2                      # the real-axis ends are -1/g at the disk gain margins
    assert sorted([c - r, c + r]) == pytest.approx([-(1 + a) / (1 - a), -(1 - a) / (1 + a)])
    with pytest.raises(ParameterError, match="alpha must be"):
        disk_margin_disk(2.0)


def test_pd_loop_static_gains_and_frequency_response(design):
    pd_ = PD(design)
    lp = loop_response(pd_, t_end=120.0)
    tail = lp.t > 100.0                # the flexible modes ring (undamped plant): average them out
    assert np.mean(lp.step_theta[tail]) == pytest.approx(1.0, abs=2e-3)         # type-1 loop
    assert np.mean(lp.dist_theta[tail]) == pytest.approx(1.0 / pd_.kp, rel=2e-3)  # theta = d / kp
    # L against python-control's evaluation of the same loop (controllers.analysis)
    sys = loop_transfer(pd_)
    k = np.linspace(0, len(lp.w) - 1, 40).astype(int)
    ref = np.array([complex(np.squeeze(sys(np.exp(1j * w * sys.dt)))) for w in lp.w[k]])
    # 1e-6: the plots take the split form of FrequencyResponse (the free hub's Jordan block apart),
    # within 1e-7 of python-control's solves here near the undamped resonances (issue 28, speed)
    np.testing.assert_allclose(lp.L[k], ref, rtol=1e-6)
    np.testing.assert_allclose(FrequencyResponse(*loop_matrices(pd_))(np.exp(1j * lp.w[k] * lp.dt), precise=True),
                               ref, rtol=1e-8)                  # the margins' precise points: as before
    # S and T add to one; the peaks are the grid maxima
    np.testing.assert_allclose(lp.S + lp.T, 1.0, atol=1e-12)
    peaks = sensitivity_peaks(lp)
    assert peaks["S"][0] == pytest.approx(np.max(np.abs(lp.S)))


@pytest.mark.parametrize("kind", ["lqr", "lqg"])
def test_disk_margin_matches_loop_margins(design, kind):
    ctrl = LQR(design) if kind == "lqr" else LQG(design)
    lp = loop_response(ctrl, n_points=3000)
    m = loop_margins(ctrl)
    assert lp.disk_margin == pytest.approx(m.disk_margin_grid, rel=1e-9)
    assert lp.disk_margin == pytest.approx(m.disk_margin, rel=1e-3)
    np.testing.assert_allclose(np.sort_complex(lp.poles), np.sort_complex(np.linalg.eigvals(
        control.feedback(loop_transfer(ctrl), 1).A)), atol=1e-9)


def test_richer_model_poles_and_aliased_modes_match_spillover():
    naive = LQG(DesignModel.build(), LQGSettings(robust=False))
    ev = evaluation_model(naive, modes=10)
    lp = loop_response(naive, ev)
    ref = loop_poles(naive, 10)                         # the same loop built by study.spillover
    assert np.max(np.abs(lp.poles)) == pytest.approx(ref.spectral_radius, abs=1e-6)
    assert np.max(np.abs(lp.poles)) == pytest.approx(1.011, abs=5e-4)   # unstable: spillover
    worst = int(np.argmax(np.abs(lp.poles)))
    assert lp.aliased_hz[worst] == pytest.approx(52.4, abs=0.5)       # mode 7 folded to 47.6 Hz
    fs = 1 / lp.dt
    for z, f in zip(lp.poles, lp.aliased_hz):
        if np.isfinite(f):
            assert f > fs / 2
            folded = abs(f - fs * round(f / fs))
            assert abs(np.angle(z)) / (2 * np.pi * lp.dt) == pytest.approx(folded, abs=0.3)
    assert np.all(np.isnan(loop_response(naive).aliased_hz))          # 5 modes: all below 50 Hz


def test_loop_figure_panels_and_units(design, tmp_path):
    ctrl = LQR(design)
    ev = evaluation_model(ctrl, modes=4)
    fig = loop_figure(ctrl, ev, t_end=5.0)
    assert isinstance(fig, Figure) and len(fig.axes) == 10
    for ax in fig.axes:
        assert re.search(r"\[.+\]", ax.get_ylabel()), ax.get_title()
        assert re.search(r"\[.+\]", ax.get_xlabel()) or ax.get_xlabel() == "", ax.get_title()
        assert ax.get_title() or ax.get_ylabel() == "phase of L [deg]"      # the Bode pair has one title
    nyquist = fig.axes[1]
    disk = [p for p in nyquist.patches]
    drawn = [lp.disk_margin for lp in (loop_response(ctrl), loop_response(ctrl, ev)) if 0 < lp.disk_margin < 2]
    assert len(disk) == len(drawn) >= 1          # a disk per stable loop (none for an unstable one)
    c, r = disk_margin_disk(loop_response(ctrl).disk_margin)
    x = disk[0].get_path().vertices[:, 0]
    assert (x.min(), x.max()) == pytest.approx((c - r, c + r), abs=1e-3)
    fig.savefig(tmp_path / "loops.png", dpi=60)
    assert (tmp_path / "loops.png").stat().st_size > 10_000


def test_bad_input():
    with pytest.raises(ParameterError, match="loops must be"):
        plot_loop([])
    from controllers import OpenLoop
    with pytest.raises(ParameterError, match="ctrl must be a linear controller"):
        loop_response(OpenLoop(DesignModel.build(n_modes=1)))
    with pytest.raises(ParameterError, match="t_end must be"):
        loop_response(PD(DesignModel.build(n_modes=1)), t_end=-1.0)
    with pytest.raises(ParameterError, match="modes must be an integer in 2..20"):
        evaluation_model(PD(DesignModel.build(n_modes=2)), modes=1)


def test_markdown_page(tmp_path):
    from matplotlib.figure import Figure as F
    fig = F(figsize=(2, 1))
    fig.subplots().plot([0, 1])
    fig.savefig(tmp_path / "a.png")
    md = ("# T <1>\n\nText with **bold**, `code` and *it*.\n\n- one\n  more\n- two\n\n"
          "| x | y |\n|---|---|\n| 1 | **no** |\n\n![fig a](a.png)\n")
    page = markdown_to_html(md, tmp_path)
    assert "<title>T &lt;1&gt;</title>" in page and "<h1>T &lt;1&gt;</h1>" in page
    assert "<li>one more</li>" in page and "<td><strong>no</strong></td>" in page
    assert "<code>code</code>" in page and "<em>it</em>" in page
    src = re.search(r'<img src="data:image/png;base64,([^"]+)" alt="fig a">', page).group(1)
    import base64
    assert base64.b64decode(src) == (tmp_path / "a.png").read_bytes()
    with pytest.raises(ParameterError, match="image 'b.png' of the report is missing"):
        markdown_to_html("![b](b.png)", tmp_path)


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory, fast_backend_module):
    out = tmp_path_factory.mktemp("loops") / "cmp"
    write_outputs(compare(None, "slew", "openloop,pd,lqr",
                          CompareSettings(plant=PlantChoice(plant_modes=3), design=DesignChoice(design_modes=2))), out)
    return out


def test_report_links_one_overlaid_loop_figure_and_html_embeds_it(report_dir):
    """Issue 28 (speed): one loop figure with every linear controller overlaid (loops.png) in place
    of one figure per controller (loops_pd.png, loops_lqr.png, ...): changed deliberately."""
    md = (report_dir / "report.md").read_text()
    assert "![loop plots](loops.png)" in md
    assert (report_dir / "loops.png").stat().st_size > 50_000
    assert not list(report_dir.glob("loops_*.png"))
    manifest = json.loads((report_dir / "MANIFEST.json").read_text())
    assert {"loops.png", "report.html"} <= set(manifest["files"])
    page = (report_dir / "report.html").read_text()
    assert page.count('<img src="data:image/png;base64,') == len(re.findall(r"!\[[^\]]*\]\(", md)) == 4
    assert 'src="loops' not in page and "<table>" in page


def test_overlaid_loop_figure_panels_colours_disks_and_plain_ticks(design):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from hubbeam_ctrl.plots.loops import plot_loop_comparison
    loops = [loop_response(PD(design), label="PD", t_end=5.0), loop_response(LQR(design), label="LQR", t_end=5.0)]
    fig = plot_loop_comparison(loops, "t", colors=["tab:orange", "tab:blue"])
    assert len(fig.axes) == 6
    for ax in fig.axes:
        assert re.search(r"\[.+\]", ax.get_ylabel()) and re.search(r"\[.+\]", ax.get_xlabel()), ax.get_title()
    bode, nyquist, sens, zplane, step, dist = fig.axes
    for ax, data in ((bode, [20 * np.log10(np.abs(lp.L)) for lp in loops]), (step, [lp.step_tip for lp in loops]),
                     (dist, [1e3 * lp.dist_tip for lp in loops])):
        lines = [ln for ln in ax.lines if len(ln.get_ydata()) > 2]
        assert [ln.get_color() for ln in lines] == ["tab:orange", "tab:blue"]
        assert [ln.get_linestyle() for ln in lines] == ["-", "--"]          # equal loops stay visible
        for ln, y in zip(lines, data):
            np.testing.assert_allclose(ln.get_ydata(), y, rtol=1e-12)
    assert [t.get_text() for t in bode.get_legend().get_texts()] == ["PD", "LQR"]
    peak = sensitivity_peaks(loops[1])["S"]
    assert any(f"LQR: max|S| {peak[0]:.2f} at {peak[1] / (2 * np.pi):.3g} Hz" in t.get_text()
               for t in sens.get_legend().get_texts())
    stable = [lp.disk_margin for lp in loops if 0 < lp.disk_margin < 2]
    assert len(nyquist.patches) == len(stable) >= 1                       # a disk per stable loop
    c, r = disk_margin_disk(stable[-1])
    x = nyquist.patches[-1].get_path().vertices[:, 0]
    assert (x.min(), x.max()) == pytest.approx((c - r, c + r), abs=1e-3)
    FigureCanvasAgg(fig).draw()                   # log axes: plain labels, no mathtext, no minor ticks
    for ax in (bode, sens):
        labels = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
        assert labels and not any("$" in t for t in labels) and "1" in labels
        assert ax.xaxis.get_minor_locator()() == []
    with pytest.raises(ParameterError, match="colors must have one entry per loop"):
        plot_loop_comparison(loops, colors=["k"])


_PROBE = """<script>
window.__errors = [];
window.addEventListener("error", function (e) {
  window.__errors.push(String(e.message || (e.target && e.target.outerHTML.slice(0, 80)))); }, true);
var _ce = console.error;
console.error = function () { window.__errors.push("console.error: " + Array.from(arguments).join(" ")); };
window.addEventListener("load", function () {
  var imgs = Array.from(document.images).map(function (im) {
    return [im.alt, im.complete, im.naturalWidth, im.naturalHeight]; });
  var pre = document.createElement("pre"); pre.id = "probe-result";
  pre.textContent = JSON.stringify({images: imgs, errors: window.__errors});
  document.body.appendChild(pre);
});
</script>
"""


def _chromium():
    return next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)),
                None)


@pytest.mark.skipif(_chromium() is None, reason="no Chromium on this machine (Debian: apt-get install chromium); "
                    "report.html is then checked without a browser only")
def test_report_html_in_headless_chromium(report_dir, tmp_path):
    """The page loads with no error and every figure decodes (naturalWidth > 0), in a real browser.

    A copy of report.html gets a probe script as the first thing in <head>: it records errors
    (script errors, failed resources, console.error) and, on load, writes each image's decoded
    size into the DOM, which ``--dump-dom`` prints.
    """
    page = (report_dir / "report.html").read_text()
    probe = tmp_path / "report_probe.html"
    probe.write_text(page.replace("<head>\n", "<head>\n" + _PROBE, 1))
    run = subprocess.run([_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                          "--enable-logging=stderr", "--v=0", "--dump-dom", probe.as_uri()],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    found = re.search(r'<pre id="probe-result">(.*?)</pre>', run.stdout, re.S)
    assert found, run.stdout[-2000:]
    result = json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    assert result["errors"] == []
    assert len(result["images"]) == 4
    for alt, complete, width, height in result["images"]:
        assert complete and width > 300 and height > 200, alt
    console = [ln for ln in run.stderr.splitlines() if "CONSOLE" in ln]
    assert console == []


def test_plain_log_ticks_label_decades_without_mathtext():
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from hubbeam_ctrl.plots.loops import plain_log_ticks
    fig = Figure(figsize=(3, 8))
    ax = fig.subplots()
    ax.semilogy([0, 1], [1e-5, 10.0])
    ax.set_ylim(1e-5, 10.0)
    plain_log_ticks(ax.yaxis)
    FigureCanvasAgg(fig).draw()
    labels = {t.get_text() for t in ax.get_yticklabels() if t.get_text()}
    assert {"1e-05", "1e-04", "0.001", "0.01", "0.1", "1", "10"} <= labels
    assert all(re.fullmatch(r"\d+(\.\d+)?|1e[-+]\d\d", t) for t in labels), labels
    assert ax.yaxis.get_minor_locator()() == []
