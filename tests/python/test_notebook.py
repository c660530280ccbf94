"""examples/python_prism_sweep.ipynb, executed as a user would run it: a kernel of the test
virtualenv (matplotlib, vtk) importing the `tsim` package from the wheel (scripts/wheel),
in a directory of its own. Every cell must run; the outputs that state a result are read.
"""

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
