"""The Python package (python/): its wheel, built by scripts/wheel, installed into a fresh
virtualenv (its dependencies from PyPI, nothing of the checkout's), gives the `tsim`
command and the Python API, with tsim's HDF5 linked in privately beside h5py's own.

Each check compares with the `tsim` binary built against the system HDF5: the same
program, so the same numbers to the bit.
"""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pytest
from ruamel.yaml import YAML

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def venv(tmp_path_factory, wheel):
    """A fresh virtualenv with the wheel installed."""
    env_dir = tmp_path_factory.mktemp("venv")
    subprocess.run([sys.executable, "-m", "venv", env_dir], check=True)
    pip = [env_dir / "bin" / "python", "-m", "pip", "install", "--quiet", "--disable-pip-version-check"]
    subprocess.run([*pip, wheel], check=True)
    return env_dir


def in_venv(venv, *args, cwd, **kw):
    # A clean environment: no checkout on the path, no TSIM_PYTHON, no HDF5 variables.
    env = {"PATH": f"{venv / 'bin'}:/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root")}
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, **kw)


def test_the_extension_exports_no_hdf5_and_links_no_system_hdf5(venv):
    (so,) = (venv / "lib").glob("python3*/site-packages/tsim/_tsim*.so")
    exported = subprocess.run(["nm", "-D", "--defined-only", so], check=True, capture_output=True, text=True).stdout
    names = [line.split()[-1] for line in exported.splitlines()]
    # A Python extension exports its init function only: HDF5's H5* symbols stay private,
    # so h5py's HDF5 in the same process cannot be bound to them, nor they to it.
    assert names == ["PyInit__tsim"], names
    linked = subprocess.run(["ldd", so], check=True, capture_output=True, text=True).stdout
    assert "hdf5" not in linked and "libz" not in linked, linked


def test_the_command_runs_the_paper_case_as_the_binary_does(venv, tsim_bin, tmp_path):
    done = in_venv(venv, "tsim", "run", ROOT / "configs" / "paper.yaml", "--out", tmp_path / "wheel", "--quiet", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    subprocess.run([tsim_bin, "run", ROOT / "configs" / "paper.yaml", "--out", tmp_path / "bin", "--quiet"], check=True, capture_output=True)
    a = json.loads((tmp_path / "wheel" / "paper" / "summary.json").read_text())
    b = json.loads((tmp_path / "bin" / "paper" / "summary.json").read_text())
    assert a[0]["status"] == "complete"
    assert untimed(a[0]["summary"]) == untimed(b[0]["summary"])
    with h5py.File(tmp_path / "wheel" / "paper" / "paper" / "result.h5") as fa, h5py.File(tmp_path / "bin" / "paper" / "paper" / "result.h5") as fb:
        assert fa.attrs["status"] == fb.attrs["status"] == b"complete"
        for name in ["deployment/position", "deployment/member_force", "folding/position"]:
            np.testing.assert_array_equal(fa[name][()], fb[name][()], err_msg=name)
    # Usage errors are the binary's, and exit 2 without ending a Python process badly.
    bad = in_venv(venv, "tsim", "run", cwd=tmp_path)
    assert bad.returncode == 2 and "CONFIG" in bad.stderr.upper(), bad.stderr


def untimed(summary):
    """A summary without its wall times (stage_seconds, each stage's wall_seconds)."""
    if isinstance(summary, dict):
        return {k: untimed(v) for k, v in summary.items() if k not in ("stage_seconds", "wall_seconds")}
    return summary


def prism_arrays():
    """configs/examples/prism_selfweight.yaml's model as arrays."""
    cfg = YAML(typ="safe").load((ROOT / "configs" / "examples" / "prism_selfweight.yaml").read_text())
    nodes = cfg["model"]["nodes"]
    ids = [n["id"] for n in nodes]
    members = cfg["model"]["members"]
    return cfg, {
        "nodes": np.array([n["xyz"] for n in nodes]),
        "members": np.array([[ids.index(a) for a in m["nodes"]] for m in members]),
        "kind": [m["kind"] for m in members],
        "node_ids": ids,
        "member_ids": [m["id"] for m in members],
        "fix": {n["id"]: "".join(n["fix"]) for n in nodes if "fix" in n},
        "rest_length": np.array([m["rest_length"] for m in members]),
        "member_groups": {g: [m["id"] for m in members if g in m["groups"]] for g in ["strut", "ring_bottom", "ring_top", "vertical"]},
        "node_groups": cfg["model"]["groups"],
    }


# Run inside the fresh virtualenv: h5py (with its own HDF5) imported and a file of its own
# open before tsim runs, a model built from NumPy arrays, tsim's files read back by h5py and
# xarray in the same process and by tsim's own HDF5 while h5py holds them open, h5py's file
# written again after.
API_SCRIPT = textwrap.dedent(
    """
    import json, sys
    import h5py, numpy as np
    arrays = json.load(open("arrays.json"))
    mine = h5py.File("mine.h5", "w")
    mine["x"] = np.arange(5.0)
    import tsim
    cfg = arrays.pop("config")
    for key in ["nodes", "members", "rest_length"]:
        arrays[key] = np.array(arrays[key])
    cfg["model"] = tsim.model(**arrays)
    run = tsim.run(cfg, out="runs")
    assert run.failed == {}, run.failed
    with h5py.File(run.path(), "r") as f:
        assert f.attrs["status"] == b"complete"
        position = f["static/position"][()]
    ds = run.result(stage="static")
    assert np.array_equal(ds["position"].values, position)
    summary = run.summary()
    # tsim's HDF5 reads result.h5 again (`tsim collect`, in-process) while h5py holds it open.
    held = h5py.File(run.path(), "r")
    assert tsim._tsim.cli(["tsim", "collect", str(run.directory)]) == 0
    assert np.array_equal(run.collected().static_position.values[0], position)
    held.close()
    mine["y"] = position
    mine.close()
    with h5py.File("mine.h5", "r") as f:
        assert np.array_equal(f["y"][()], position)
    # The same prism with its top ring one clustered cable, from the arrays.
    ring = {"top_ring": ["ct0", "ct1", "ct2"]}
    clustered = dict(cfg, name="clustered", model=tsim.model(**arrays, clusters=ring))
    assert clustered["model"]["clusters"] == [{"id": "top_ring", "members": ["ct0", "ct1", "ct2"]}]
    # With capstan friction: the mapping form.
    rough = tsim.model(**arrays, clusters={"top_ring": {"members": ["ct0", "ct1", "ct2"], "friction": 0}})["clusters"]
    assert rough == [{"id": "top_ring", "members": ["ct0", "ct1", "ct2"], "friction": 0.0}]
    loop = tsim.run(clustered, out="runs").result(stage="static")
    # The cable's tension is its first member's; the others carry it to round-off.
    tension = loop["cluster_tension"].values[:, 0]
    assert np.array_equal(tension, loop["member_force"].sel(member="ct0").values)
    assert np.allclose(loop["member_force"].sel(member=["ct1", "ct2"]).values, tension[:, None], rtol=1e-9, atol=0)
    try:
        tsim.run({"name": "broken", "model": {"nodes": []}}, out="runs")
    except tsim.ConfigError as e:
        config_error = str(e)
    print(json.dumps({"position": position.tolist(), "rows": len(summary), "h5py_hdf5": h5py.version.hdf5_version,
                      "tsim_hdf5": tsim.hdf5_version(), "config_error": config_error}))
    """
)


def test_the_api_runs_a_model_from_arrays_beside_h5py(venv, tsim_bin, tmp_path):
    cfg, arrays = prism_arrays()
    del cfg["model"]
    arrays = {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in arrays.items()}
    (tmp_path / "arrays.json").write_text(json.dumps({**arrays, "config": cfg}))
    (tmp_path / "api.py").write_text(API_SCRIPT)
    done = in_venv(venv, venv / "bin" / "python", "api.py", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    got = json.loads(done.stdout)
    # Two HDF5 libraries in one process, each with its own files.
    assert got["h5py_hdf5"] != got["tsim_hdf5"], got
    assert got["rows"] == 1
    assert "<dict config>" in got["config_error"], got["config_error"]
    # The dict built from arrays is the YAML file's model: the same static stage to the bit.
    subprocess.run([tsim_bin, "run", ROOT / "configs" / "examples" / "prism_selfweight.yaml", "--out", tmp_path / "bin", "--quiet"],
                   check=True, capture_output=True)
    with h5py.File(tmp_path / "bin" / "prism_selfweight" / "prism_selfweight" / "result.h5") as f:
        np.testing.assert_array_equal(np.array(got["position"]), f["static/position"][()])


# A long run from Python, stopped by SIGINT (Ctrl-C, a notebook's stop button) once its
# result.h5 exists: KeyboardInterrupt is raised after the case closed its file.
INTERRUPT_SCRIPT = textwrap.dedent(
    """
    import json, sys
    import h5py, tsim
    try:
        tsim.run(sys.argv[1], out="runs")
        outcome = "finished"
    except KeyboardInterrupt:
        outcome = "KeyboardInterrupt"
    with h5py.File("runs/prism_drop/prism_drop/result.h5", "r") as f:
        status = f.attrs["status"].decode()
    summary = json.load(open("runs/prism_drop/summary.json"))
    print(json.dumps({"outcome": outcome, "status": status, "case": summary[0]["status"]}))
    """
)


def test_ctrl_c_stops_a_python_run_and_closes_its_files(venv, tmp_path):
    import signal
    import time

    text = (ROOT / "configs" / "examples" / "prism_drop.yaml").read_text()
    long = text.replace("duration: 3.0,", "duration: 300.0,")  # minutes: far past the signal
    assert long != text
    (tmp_path / "long.yaml").write_text(long)
    (tmp_path / "interrupt.py").write_text(INTERRUPT_SCRIPT)
    env = {"PATH": f"{venv / 'bin'}:/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root")}
    proc = subprocess.Popen([venv / "bin" / "python", "interrupt.py", "long.yaml"], cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    result = tmp_path / "runs" / "prism_drop" / "prism_drop" / "result.h5"
    deadline = time.monotonic() + 60
    while not result.exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.1)
    time.sleep(1.0)  # into the transient
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    got = json.loads(out)
    assert got == {"outcome": "KeyboardInterrupt", "status": "interrupted", "case": "interrupted"}, (got, err)
