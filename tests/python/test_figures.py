"""The figures script (issue 7) on a real, short run: every figure exists, has its size in
pixels, and shows something. Run from the repository root:

    .venv/bin/python -m pytest -q tests/python/test_figures.py

The run is tests/fixtures/small_sweep.yaml (a 3-strut prism through every stage, 4 cases,
well under a second) made by the release binary; drawing takes a few seconds per case.
"""

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
FIGURES = ROOT / "scripts" / "figures"

# Expected (width, height) in pixels: scripts/figures.py fixes each figure's size in inches
# and saves at 100 dpi without a tight bounding box, so these are exact.
CASE_SIZES = {
    "structure": (1200, 600),
    "formfinding": (1000, 500),
    "free_vibration_energy": (800, 450),
    "eigen_spectrum": (800, 450),
    "mode_shapes": (1200, 750),
    "folding": (1200, 750),
    "deployment_snapshots": (1200, 750),
    "deployment_top_node": (800, 450),
    "deployment_energy": (1200, 450),
}
SWEEP_SIZES = {"sweep_overview": (1200, 450)}
STAGE_SIZE = (1200, 450)  # stage_<name>.png

# "Not blank", two ways, on RGB values in [0, 1]:
# - Variance of the grey level above 1e-3. A blank (single-colour) canvas has variance 0;
#   any frame with axes, ticks and labels is already above 4e-3 at these sizes, and the
#   figures measured 0.011 to 0.023 when this test was written. So this catches a figure
#   saved before anything was drawn (white, or one flat colour), not an empty axes.
# - Fraction of coloured pixels (max - min channel > 0.2) above 0.3 %. Matplotlib's frames,
#   3-D panes, grids and text are all grey, so empty axes score exactly 0; a legend alone
#   stays below 0.15 % (7 entries measured); the drawn members and curves scored 0.6 % to 4 %. This catches
#   axes that were set up but got no data.
MIN_VARIANCE = 1e-3
MIN_COLOURED = 0.003



@pytest.fixture(scope="session")
def sweep(tsim_bin, tmp_path_factory):
    out = tmp_path_factory.mktemp("runs")
    subprocess.run([tsim_bin, "run", ROOT / "tests/fixtures/small_sweep.yaml", "--out", out, "--quiet"], check=True, cwd=ROOT)
    return out / "small"


def figures(*args):
    return subprocess.run([FIGURES, *map(str, args)], check=True, capture_output=True, text=True, cwd=ROOT)


def check_png(path, size):
    assert path.is_file(), f"{path.name} missing"
    img = mpimg.imread(path)
    assert (img.shape[1], img.shape[0]) == size, f"{path.name}: {img.shape[1]}x{img.shape[0]} px, expected {size}"
    rgb = img[..., :3].astype(float)
    variance = rgb.mean(axis=2).var()
    coloured = (rgb.max(axis=2) - rgb.min(axis=2) > 0.2).mean()
    assert variance > MIN_VARIANCE, f"{path.name} looks blank: grey-level variance {variance:.2e}"
    assert coloured > MIN_COLOURED, f"{path.name} has axes but no data: {100 * coloured:.3f} % coloured pixels"


def test_case_figures(sweep, tmp_path):
    case = sweep / "cable-rubber_zeta-0.1"
    assert (case / "result.h5").is_file()
    out = tmp_path / "figs"
    figures(case, "--out", out)
    for name, size in CASE_SIZES.items():
        check_png(out / f"{name}.png", size)
    assert sorted(p.stem for p in out.glob("*.png")) == sorted(CASE_SIZES)


def test_result_h5_path_default_out_and_svg(sweep):
    # Given the file rather than its directory, figures go to <case dir>/figures; --svg adds
    # an SVG of each (two figures here, to keep the test short).
    case = sweep / "cable-nylon_zeta-0.05"
    figures(case / "result.h5", "--only", "eigen_spectrum", "deployment_top_node", "--svg")
    out = case / "figures"
    for name in ["eigen_spectrum", "deployment_top_node"]:
        check_png(out / f"{name}.png", CASE_SIZES[name])
        svg = out / f"{name}.svg"
        assert svg.is_file() and "<svg" in svg.read_text()[:2000], f"{svg.name} missing or not SVG"
    assert sorted(p.name for p in out.iterdir()) == sorted(
        f"{n}.{e}" for n in ["eigen_spectrum", "deployment_top_node"] for e in ["png", "svg"])


def test_sweep_overview(sweep):
    assert (sweep / "summary.csv").is_file() and not (sweep / "result.h5").exists()
    res = figures(sweep)
    for name, size in SWEEP_SIZES.items():
        check_png(sweep / "figures" / f"{name}.png", size)
    assert "sweep_overview.png" in res.stdout


def test_absent_stages_are_skipped(tsim_bin, tmp_path):
    # Form-finding and folding only: the other figures are skipped with a note, not an error.
    config = tmp_path / "partial.yaml"
    config.write_text(
        "name: partial\n"
        "model:\n  tower: { struts: 3, stages: 1, radius: 2.0, strut_length: 5.0 }\n"
        "formfinding: {}\n"
        "substitution: { strut: aluminium, cable: rubber }\n"
        "masses: paper\n"
        "folding:\n  steps: 4\n  prescribe: [{ group: top, axis: z, displacement: -0.5 }]\n"
    )
    subprocess.run([tsim_bin, "run", config, "--out", tmp_path / "runs", "--quiet"], check=True)
    case = next((tmp_path / "runs").rglob("result.h5")).parent
    res = figures(case)
    drawn = {"structure", "formfinding", "folding"}
    for name in drawn:
        check_png(case / "figures" / f"{name}.png", CASE_SIZES[name])
    assert sorted(p.stem for p in (case / "figures").glob("*.png")) == sorted(drawn)
    for name in set(CASE_SIZES) - drawn:
        assert f"skipped {name}.png" in res.stdout


def test_tsim_figures_draws_from_any_directory(sweep, tsim_bin, tmp_path):
    # The script built into the binary, run from a directory with no scripts/ in it, by
    # the Python named in TSIM_PYTHON: the case's figures, each announced with its path.
    case = sweep / "cable-nylon_zeta-0.1"
    out = tmp_path / "figs"
    res = subprocess.run([tsim_bin, "figures", case, "--out", out, "--only", "formfinding", "folding"],
                         capture_output=True, text=True, cwd=tmp_path, env={**os.environ, "TSIM_PYTHON": sys.executable})
    assert res.returncode == 0, res.stderr
    for name in ("formfinding", "folding"):
        check_png(out / f"{name}.png", CASE_SIZES[name])
        assert f"wrote {out / name}.png" in res.stdout, res.stdout


def load_figures_module():
    spec = importlib.util.spec_from_file_location("figures", ROOT / "scripts" / "figures.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_titles_cite_the_paper_only_for_its_tower(sweep, tsim_bin, tmp_path):
    # "(paper Table 2)" on a 3-strut prism misleads; on the paper's tower it is the point.
    figures_module = load_figures_module()
    prism = figures_module.Case(sweep / "cable-nylon_zeta-0.1" / "result.h5")
    assert not prism.paper and prism.ref("Table 2") == ""
    config = tmp_path / "paper.yaml"
    config.write_text((ROOT / "configs" / "paper.yaml").read_text().replace("figures: true", "figures: false"))
    subprocess.run([tsim_bin, "run", config, "--out", tmp_path, "--quiet"], check=True)
    paper = figures_module.Case(tmp_path / "paper" / "paper" / "result.h5")
    assert paper.paper and paper.ref("Table 2") == " (paper Table 2)"


def test_no_rayleigh_draws_no_damping_axis(tsim_bin, tmp_path):
    # An eigen stage without `rayleigh` records α = β = 0; the spectrum had an empty
    # modal-damping axis then. Now one axes, and the title says there is no damping.
    text = (ROOT / "tests" / "fixtures" / "small_sweep.yaml").read_text().split("masses:")[0] + "eigen: {}\n"
    config = tmp_path / "eigen_only.yaml"
    config.write_text(text)
    subprocess.run([tsim_bin, "run", config, "--out", tmp_path, "--quiet"], check=True)
    figures_module = load_figures_module()
    case = figures_module.Case(tmp_path / "small" / "small" / "result.h5")
    fig = figures_module.eigen_figure(case, 100)
    assert len(fig.axes) == 1 and fig.axes[0].get_title().endswith("; no Rayleigh damping"), fig.axes[0].get_title()


def test_a_given_model_and_a_stage_list_get_their_figures(tsim_bin, tmp_path):
    # configs/examples/prism_drop.yaml: a model given as nodes and members (no form-finding)
    # and the stages `eigen`, `drop` (transient) and `rest` (static), none of the paper's
    # names: the structure at its equilibrium, the eigen figures and one figure per stage.
    subprocess.run([tsim_bin, "run", ROOT / "configs" / "examples" / "prism_drop.yaml", "--out", tmp_path, "--quiet"], check=True)
    case = tmp_path / "prism_drop" / "prism_drop"
    res = figures(case)
    check_png(case / "figures" / "structure.png", CASE_SIZES["structure"])
    for name in ["stage_drop", "stage_rest"]:
        check_png(case / "figures" / f"{name}.png", STAGE_SIZE)
        assert f"wrote {case / 'figures' / name}.png" in res.stdout
    assert sorted(p.stem for p in (case / "figures").glob("*.png")) == sorted(
        ["structure", "eigen_spectrum", "mode_shapes", "stage_drop", "stage_rest"])
    # --only takes a stage's figure by name and refuses one that is not there.
    only = subprocess.run([FIGURES, case, "--out", tmp_path / "only", "--only", "stage_rest"], capture_output=True, text=True, cwd=ROOT)
    assert only.returncode == 0 and sorted(p.name for p in (tmp_path / "only").iterdir()) == ["stage_rest.png"]
    wrong = subprocess.run([FIGURES, case, "--only", "stage_fall"], capture_output=True, text=True, cwd=ROOT)
    assert wrong.returncode != 0 and "stage_fall" in wrong.stderr and "stage_drop" in wrong.stderr
