"""examples/python_prism_sweep.ipynb, executed as a user would run it: a kernel of the test
virtualenv (matplotlib, vtk) importing the `tsim` package from the wheel (scripts/wheel),
in a directory of its own. Every cell must run; the outputs that state a result are read.
"""

import ast
import os
import subprocess
import sys
from pathlib import Path

import nbformat
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[2]


def text_of(cell):
    return "".join(o.get("text", "") + str(o.get("data", {}).get("text/plain", "")) for o in cell.outputs)


def test_the_notebook_runs_from_the_wheel(wheel, tmp_path, monkeypatch):
    packages = tmp_path / "packages"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", packages, wheel], check=True)
    # The kernel inherits the environment: tsim from the wheel, the rest from this virtualenv.
    monkeypatch.setenv("PYTHONPATH", str(packages))
    nb = nbformat.read(ROOT / "examples" / "python_prism_sweep.ipynb", as_version=4)
    # Timeout per cell: the sweep cell takes some 10 s on 2 cores; a hung kernel fails.
    NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert "with HDF5 2." in text_of(code[0])
    assert "3 complete" in text_of(code[2])  # <tsim.Run runs/notebook_prism (3 complete)>
    assert any("image/png" in o.get("data", {}) for o in code[4].outputs), "the collected.h5 plot drew nothing"
    assert "6 points, 12 cells, 501 steps" in text_of(code[5])
    assert "equals result.h5's: True" in text_of(code[5])


def test_figures_from_python(wheel, tmp_path):
    """`Run.figures()` draws a case's figures from Python, with the interpreter it runs in."""
    packages = tmp_path / "packages"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", packages, wheel], check=True)
    script = (
        "import sys, tsim\n"
        f"run = tsim.run({str(ROOT / 'configs' / 'examples' / 'prism_selfweight.yaml')!r}, out='runs')\n"
        "folder = run.figures(options=['--dpi', '40'])\n"
        "print(sorted(p.name for p in folder.glob('*.png')))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "TSIM_PYTHON"}
    done = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, env={**env, "PYTHONPATH": str(packages)},
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    drawn = ast.literal_eval(done.stdout.splitlines()[-1])  # the list printed last
    assert drawn == ["eigen_spectrum.png", "mode_shapes.png", "stage_static.png", "structure.png"], drawn
    assert all((tmp_path / "runs" / "prism_selfweight" / "prism_selfweight" / "figures" / name).stat().st_size > 1000 for name in drawn)
