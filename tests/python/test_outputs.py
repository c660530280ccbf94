"""Interop tests of tsim's outputs (issue 4) with the Python readers users rely on.

The data come from `examples/write_sample.rs`, which writes the paper's tower with synthetic
but known values (documented there; recomputed here). Run from the repository root:

    .venv/bin/pytest tests/python
"""

import json
import os
import signal
import subprocess
import time
import zlib
from collections import defaultdict
from pathlib import Path

import h5py
import numpy as np
import pytest
import xarray as xr
from mcap.reader import make_reader
from mcap.records import Footer
from mcap.stream_reader import StreamReader
from mcap_protobuf.decoder import DecoderFactory

ROOT = Path(__file__).resolve().parents[2]
EVERY = 2
DT = 1e-3
STEPS = {"free_vibration": 301, "folding": 21, "deployment": 301}
GROUPS = ["model", "formfinding", "eigen", "free_vibration", "folding", "deployment"]
PER_STEP_TOPICS = ["/tsim/scene", "/tsim/energy", "/tsim/members"]


def recorded_steps(last):
    """Steps kept by the output stride: multiples of EVERY, and always the last."""
    steps = list(range(0, last + 1, EVERY))
    return steps if steps[-1] == last else steps + [last]


@pytest.fixture(scope="session")
def sample_bin():
    subprocess.run(["cargo", "build", "--release", "--example", "write_sample"], cwd=ROOT, check=True)
    meta = subprocess.run(["cargo", "metadata", "--format-version", "1", "--no-deps"], cwd=ROOT, check=True, capture_output=True, text=True)
    return Path(json.loads(meta.stdout)["target_directory"]) / "release" / "examples" / "write_sample"


@pytest.fixture(scope="session")
def sample(sample_bin, tmp_path_factory):
    out = tmp_path_factory.mktemp("sample")
    subprocess.run([sample_bin, out, "--every", str(EVERY)], check=True)
    return out


def slow_writer(sample_bin, out):
    return subprocess.Popen([sample_bin, out, "--every", "1", "--slow"])


def open_swmr(path, timeout=30.0):
    """Opens a file being written, waiting for the writer to create it and start SWMR."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return h5py.File(path, "r", libver="latest", swmr=True)
        except (OSError, FileNotFoundError):
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)


def wait_for_rows(f, dataset, rows, timeout=30.0):
    deadline = time.monotonic() + timeout
    while True:
        ds = f[dataset]
        ds.refresh()
        if ds.shape[0] >= rows:
            return ds.shape[0]
        assert time.monotonic() < deadline, f"{dataset} stuck at {ds.shape[0]} rows"
        time.sleep(0.05)


def test_every_group_opens_in_xarray_with_named_dims(sample):
    path = sample / "result.h5"
    root = xr.open_dataset(path, engine="h5netcdf")
    assert root.attrs["status"] == "complete"
    assert root.attrs["units"] == "SI (m, N, kg, s)"
    assert root.attrs["case_id"] == "sample"
    assert root.attrs["config"] == "case: sample\n"
    assert root.attrs["tsim_version"]
    expected_dims = {
        "model": {"node": 20, "member": 50, "xyz": 3, "end": 2},
        "formfinding": {"iteration": 3, "node": 20, "member": 50, "xyz": 3},
        "eigen": {"mode": 4, "node": 20, "xyz": 3},
    }
    for g in ["free_vibration", "folding", "deployment"]:
        # support: the tower's 8 supported directions (5 base nodes in z, b0_0 in x and y,
        # b0_1 in one more).
        # pair: a strut pair's two members; clearance_event, contact: none in the sample.
        expected_dims[g] = {
            "time": len(recorded_steps(STEPS[g])), "node": 20, "member": 50, "xyz": 3, "support": 8,
            "pair": 2, "clearance_event": 0, "contact": 0,
        }
    for g in GROUPS:
        ds = xr.open_dataset(path, engine="h5netcdf", group=g)
        assert dict(ds.sizes) == expected_dims[g], g
        assert set(expected_dims[g]) <= set(ds.coords), g
        assert not any(d.startswith("phony") for d in ds.dims)
        for name, var in ds.variables.items():
            assert {"units", "long_name"} <= set(var.attrs), f"{g}/{name}"
    assert list(xr.open_dataset(path, engine="h5netcdf", group="model").xyz.values) == ["x", "y", "z"]
    folding = xr.open_dataset(path, engine="h5netcdf", group="folding")
    assert "fraction" in folding.coords and folding.fraction.dims == ("time",)
    assert folding.position.dims == ("time", "node", "xyz")
    assert "velocity" not in folding
    deployment = xr.open_dataset(path, engine="h5netcdf", group="deployment")
    assert deployment.velocity.dims == ("time", "node", "xyz")
    assert deployment.member_force.dims == ("time", "member")
    assert deployment.kinetic_energy.attrs["units"] == "J"
    # write_sample: smallest clearance 0.5 − 1e-3 s between members 0 and 1 at step s.
    steps = np.array(recorded_steps(STEPS["deployment"]))
    np.testing.assert_allclose(deployment.min_clearance.values, 0.5 - 1e-3 * steps, rtol=0, atol=1e-15)
    assert deployment.min_clearance.attrs["units"] == "m"
    assert (deployment.min_clearance_pair.values == [0, 1]).all()
    assert deployment.clearance_event_kind.attrs["flag_meanings"] == "touch pass_through"


def test_reactions_and_applied_loads_have_named_dims_and_units(sample):
    """Issue 14: `reaction (time, support)` labelled by node and axis, `applied_load (time,
    node, xyz)` and `equilibrium_error (time)`, in newtons. write_sample puts 1 N down on every
    node and shares the 20 N among the vertical supports."""
    path = sample / "result.h5"
    for g in ["free_vibration", "folding", "deployment"]:
        ds = xr.open_dataset(path, engine="h5netcdf", group=g)
        assert ds.reaction.dims == ("time", "support"), g
        assert ds.applied_load.dims == ("time", "node", "xyz"), g
        assert ds.equilibrium_error.dims == ("time",), g
        for name in ["reaction", "applied_load", "equilibrium_error"]:
            assert ds[name].attrs["units"] == "N", f"{g}/{name}"
        assert {"support", "support_node", "support_axis", "support_kind"} <= set(ds.coords), g
        assert ds.support_node.dims == ("support",)
        labels = [f"{n}.{a}" for n, a in zip(ds.support_node.values, ds.support_axis.values)]
        assert list(ds.support.values) == labels
        assert "b0_0.x" in labels and sum(a == "z" for a in ds.support_axis.values) == 5
        assert set(ds.support_kind.values) == {"support"}
        # Selection by label, and the balance of what was written: Σ R + Σ f = 0.
        vertical = ds.reaction.sel(support=ds.support_axis == "z")
        np.testing.assert_allclose(vertical.sum("support"), 20.0)
        np.testing.assert_allclose(ds.applied_load.sel(xyz="z").sum("node"), -20.0)
        assert float(ds.reaction.sel(support="b0_0.x")[0]) == 0.0


def test_values_equal_the_written_ones(sample):
    path = sample / "result.h5"
    model = xr.open_dataset(path, engine="h5netcdf", group="model")
    x0 = model.initial_position.values
    assert model.node.values[0] == "b0_0" and model.member.values[0] == "strut0_0"
    strut = model.member_kind.values == "strut"
    assert strut.sum() == 10
    ff = xr.open_dataset(path, engine="h5netcdf", group="formfinding")
    np.testing.assert_array_equal(ff.residual_norm.values, [1.0, 1e-3, 1e-9])
    np.testing.assert_array_equal(ff.member_force.values, np.where(strut, -10.0, 5.0))
    eigen = xr.open_dataset(path, engine="h5netcdf", group="eigen")
    np.testing.assert_allclose(eigen.frequency.values, np.arange(1, 5) / (2 * np.pi))
    assert list(eigen.mode.values) == [1, 2, 3, 4]
    assert eigen.attrs["rayleigh_alpha"] == 0.1 and len(eigen.attrs["damping_modes"]) == 0
    for g, last in STEPS.items():
        ds = xr.open_dataset(path, engine="h5netcdf", group=g)
        s = np.array(recorded_steps(last), dtype=float)
        if g == "folding":
            np.testing.assert_array_equal(ds.time.values, s)
            np.testing.assert_allclose(ds.fraction.values, s / last)
        else:
            np.testing.assert_allclose(ds.time.values, DT * s)
            np.testing.assert_array_equal(ds.velocity.values[:, 0, 0], s)
        np.testing.assert_allclose(ds.kinetic_energy.values, 0.5 * s)
        np.testing.assert_allclose(ds.strain_energy.values, 100 - 0.5 * s)
        np.testing.assert_allclose(ds.damping_energy.values, 0.01 * s)
        np.testing.assert_allclose(ds.external_work.values, 0.02 * s)
        np.testing.assert_allclose(ds.position.values, x0[None] + 1e-3 * s[:, None, None])
        np.testing.assert_array_equal(ds.member_length.values, np.broadcast_to(1 + s[:, None], (len(s), 50)))
    # The streamed variables carry the standard shuffle + gzip filters (tsim applies them
    # itself and stores whole chunks; any HDF5 reader must decode them, as above).
    with h5py.File(path) as f:
        for g in STEPS:
            for name in ("position", "member_force", "kinetic_energy"):
                d = f[g][name]
                assert (d.compression, d.compression_opts, d.shuffle) == ("gzip", 1, True), f"{g}/{name}"
    # An energy curve by label: kinetic energy at t = 0.1 s of deployment (step 100).
    dep = xr.open_dataset(path, engine="h5netcdf", group="deployment")
    assert dep.kinetic_energy.sel(time=0.1, method="nearest").item() == pytest.approx(50.0)


def test_stored_byte_planes_read_back_bit_for_bit(sample):
    """tsim writes the byte planes deflate does not shrink (noisy low mantissa bytes) as
    deflate's stored blocks inside the chunk's zlib stream (src/output/chunk.rs): h5py and
    xarray read such chunks exactly."""
    path = sample / "result.h5"
    s = np.array(recorded_steps(STEPS["deployment"]), dtype=float)
    x0 = xr.open_dataset(path, engine="h5netcdf", group="model").initial_position.values
    expected = x0[None] + 1e-3 * s[:, None, None]
    with h5py.File(path) as f:
        d = f["deployment/position"]
        np.testing.assert_array_equal(d[:], expected)
        mask, raw = d.id.read_direct_chunk((0, 0, 0))
        assert mask == 0  # both filters applied
        rows = d.chunks[0]
        chunk = np.zeros((rows,) + d.shape[1:])
        chunk[: min(rows, len(s))] = expected[:rows]
        planes = chunk.astype("<f8").view(np.uint8).reshape(-1, 8).T
        # The lowest plane is noise: it is in the stream verbatim (stored), and the stream
        # inflates to the shuffled chunk.
        assert planes[0][:512].tobytes() in raw
        assert zlib.decompress(raw) == planes.tobytes()
    dep = xr.open_dataset(path, engine="h5netcdf", group="deployment")
    np.testing.assert_array_equal(dep.position.values, expected)


def test_h5py_reads_a_running_case_with_swmr(sample_bin, tmp_path):
    writer = slow_writer(sample_bin, tmp_path)
    try:
        with open_swmr(tmp_path / "result.h5") as f:
            assert f.attrs["status"] == b"running"
            first = wait_for_rows(f, "free_vibration/time", 1)
            grown = wait_for_rows(f, "free_vibration/time", first + 1)
            assert grown > first
            kinetic = f["free_vibration/kinetic_energy"]
            kinetic.refresh()
            n = min(kinetic.shape[0], grown)
            np.testing.assert_allclose(kinetic[:n], 0.5 * np.arange(n))
        assert writer.wait(timeout=60) == 0
    finally:
        writer.kill()
    with h5py.File(tmp_path / "result.h5", "r") as f:
        assert f.attrs["status"] == b"complete"
        assert f["free_vibration/time"].shape == (3001,)


def test_mcap_decodes_with_foxglove_schemas(sample):
    topics = defaultdict(list)
    with open(sample / "replay.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert {c.compression for c in summary.chunk_indexes} == {"zstd"}
        schemas = {ch.topic: summary.schemas[ch.schema_id].name for ch in summary.channels.values()}
        for _, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            topics[channel.topic].append((message.log_time, decoded))
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    assert schemas["/tsim/scene"] == "foxglove.SceneUpdate"
    assert schemas["/tsim/energy"] == "energy.Energy"
    assert schemas["/tsim/members"] == "memberforces.MemberForces"
    assert schemas["/tsim/stage"] == "stagestart.StageStart"
    assert metadata["status"] == {"status": "complete"}
    assert metadata["case"]["case_id"] == "sample"

    recorded = sum(len(recorded_steps(last)) for last in STEPS.values())
    assert len(topics["/tsim/energy"]) == recorded
    # Form-finding logs its equilibrium scene and member forces, with no energy.
    assert len(topics["/tsim/scene"]) == len(topics["/tsim/members"]) == recorded + 1
    stages = [m.name for _, m in topics["/tsim/stage"]]
    assert stages == ["formfinding", "eigen", "free_vibration", "folding", "deployment"]
    for topic, messages in topics.items():
        times = [t for t, _ in messages]
        assert all(a < b for a, b in zip(times, times[1:])), topic

    energy = [m for _, m in topics["/tsim/energy"]]
    fv = [e for e in energy if e.stage == "free_vibration"]
    assert [e.step for e in fv] == recorded_steps(STEPS["free_vibration"])
    for e in fv:
        assert e.kinetic == pytest.approx(0.5 * e.step)
        assert e.total == pytest.approx(100 + 0.01 * e.step - 0.02 * e.step)
    # Stages back to back: free vibration starts 0.2 s in (after form-finding and eigen,
    # 0.1 s each) and its step 300 is logged at 0.2 + 0.3 s.
    fv_times = [t for t, m in topics["/tsim/energy"] if m.stage == "free_vibration"]
    assert fv_times[0] == pytest.approx(0.2e9, abs=1) and fv_times[-2] == pytest.approx(0.5e9, abs=1)

    # One LINE_LIST per (kind, colour): struts at the top of the compression scale (full
    # blue), cables at the top of the tension scale (full red).
    _, scene = topics["/tsim/scene"][1]
    entity = scene.entities[0]
    lines = entity.lines
    assert [(line.type, line.thickness, len(line.points)) for line in lines] == [(2, 6, 2 * 10), (2, 2, 2 * 40)]
    assert [(line.color.r, line.color.b) for line in lines] == [pytest.approx((0.10, 0.90)), pytest.approx((0.85, 0.10))]
    # Node spheres, cubes at supported nodes, at the step's positions; the legend's scale.
    with h5py.File(sample / "result.h5", "r") as f:
        supported = f["model/support"][:].any(axis=1)
        position = f["free_vibration/position"][0]
    assert len(entity.cubes) == supported.sum() > 0 and len(entity.spheres) == (~supported).sum()
    xyz = lambda prims: np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in prims])
    np.testing.assert_allclose(xyz(entity.cubes), position[supported])
    np.testing.assert_allclose(xyz(entity.spheres), position[~supported])
    assert entity.spheres[0].size.x > 0 and entity.cubes[0].size.x > entity.spheres[0].size.x
    legend = entity.texts[0].text
    assert "tension: red, max 5.00 N" in legend and "compression: blue, max 10.0 N" in legend, legend
    _, members = topics["/tsim/members"][1]
    assert members.members[0].id == "strut0_0" and members.members[0].force == -10.0


def test_kill_9_leaves_recognisably_incomplete_outputs(sample_bin, tmp_path):
    writer = slow_writer(sample_bin, tmp_path)
    try:
        with open_swmr(tmp_path / "result.h5") as f:
            wait_for_rows(f, "free_vibration/time", 300)
        os.kill(writer.pid, signal.SIGKILL)
        writer.wait(timeout=10)
    finally:
        writer.kill()
    assert writer.returncode == -signal.SIGKILL

    h5 = tmp_path / "result.h5"
    # The SWMR writer's mark stays in the superblock; h5clear -s removes it.
    subprocess.run(["h5clear", "-s", h5], check=True)
    with h5py.File(h5, "r") as f:
        assert f.attrs["status"] == b"running"
        rows = f["free_vibration/time"].shape[0]
        assert 300 <= rows < 3001
        np.testing.assert_allclose(f["free_vibration/kinetic_energy"][:], 0.5 * np.arange(rows))

    # The MCAP has no footer and no status record; its complete chunks still stream.
    with open(tmp_path / "replay.mcap", "rb") as f:
        with pytest.raises(Exception):
            make_reader(f).get_summary()
    records = []
    with open(tmp_path / "replay.mcap", "rb") as f:
        try:
            records.extend(StreamReader(f).records)
        except Exception:
            pass  # truncated mid-record
    assert not any(isinstance(r, Footer) for r in records)


def test_foxglove_layout_shows_scene_and_energy():
    layout = json.loads((ROOT / "configs" / "foxglove-layout.json").read_text())
    panels = layout["configById"]
    three_d = next(v for k, v in panels.items() if k.startswith("3D!"))
    assert three_d["topics"]["/tsim/scene"]["visible"]
    plot = next(v for k, v in panels.items() if k.startswith("Plot!"))
    assert {p["value"] for p in plot["paths"]} == {f"/tsim/energy.{f}" for f in ["kinetic", "strain", "damping", "total"]}
    assert set(panels) == {layout["layout"]["first"], layout["layout"]["second"]}


def test_a_stage_list_writes_one_group_per_entry(tsim_bin, tmp_path):
    """configs/examples/tower_stages.yaml (gravity → modes → quake → decay): each entry is a
    group named after it that opens in xarray, says its kind, and starts where the stage it
    starts from ended; the replay names the same stages in the same order."""
    config = ROOT / "configs/examples/tower_stages.yaml"
    subprocess.run([tsim_bin, "run", config, "--out", tmp_path], check=True, capture_output=True)
    case = next(tmp_path.rglob("result.h5")).parent
    kinds = {"gravity": "static", "modes": "eigen", "quake": "transient", "decay": "transient"}
    with h5py.File(case / "result.h5") as f:
        assert {g: f[g].attrs.get("stage_kind") for g in kinds} == kinds
        # The paper's groups are not written for a list.
        assert not {"static", "eigen", "free_vibration", "folding", "deployment"} & set(f)
    ds = {g: xr.open_dataset(case / "result.h5", engine="h5netcdf", group=g) for g in kinds}
    assert ds["quake"].position.dims == ("time", "node", "xyz")
    assert ds["modes"].omega2.dims == ("mode",)
    # 1 s at dt = 2 ms, every step recorded, step 0 included.
    assert ds["quake"].sizes["time"] == ds["decay"].sizes["time"] == 501
    # Each stage starts from the one before: bit-equal positions at the hand-over.
    np.testing.assert_array_equal(ds["gravity"].position[-1], ds["quake"].position[0])
    np.testing.assert_array_equal(ds["quake"].position[-1], ds["decay"].position[0])
    np.testing.assert_array_equal(ds["quake"].velocity[-1], ds["decay"].velocity[0])
    assert ds["modes"].attrs["rayleigh_beta"] > 0
    with open(case / "replay.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        stages = [m.name for _, c, _, m in reader.iter_decoded_messages() if c.topic == "/tsim/stage"]
    assert stages == ["formfinding", "gravity", "modes", "quake", "decay"]
    summary = json.loads((case / "outcome.json").read_text())["summary"]
    assert {g: summary[g]["kind"] for g in kinds} == kinds


def test_clustered_cables_replay_their_tension_and_slides(tsim_bin, tmp_path):
    """configs/examples/capstan.yaml (a rope with friction over a drum of pulleys): the
    replay's `/tsim/clusters` carries, with every scene of a stage that records rest
    lengths, each cable's tension and its slide over each pulley, equal to result.h5's
    `cluster_tension` and `pulley_slide` at the same steps; with friction the tension is the
    largest span's."""
    config = ROOT / "configs/examples/capstan.yaml"
    subprocess.run([tsim_bin, "run", config, "--out", tmp_path], check=True, capture_output=True)
    case = next(tmp_path.rglob("result.h5")).parent
    with open(case / "replay.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        schemas = {ch.topic: summary.schemas[ch.schema_id].name for ch in summary.channels.values()}
        cables, members = defaultdict(dict), defaultdict(list)
        for _, channel, _, m in reader.iter_decoded_messages():
            if channel.topic == "/tsim/clusters":
                cables[m.stage][m.step] = m.cables
            elif channel.topic == "/tsim/members":
                members[m.stage].append(m.step)
    assert schemas["/tsim/clusters"] == "cables.Cables"
    with h5py.File(case / "result.h5") as f:
        for stage in ["pull", "reel", "drop"]:
            g = f[stage]
            assert sorted(cables[stage]) == sorted(members[stage]), stage
            pulleys = [p.decode() for p in g["pulley"][:]]
            rope = [i for i, m in enumerate(g["member"][:]) if m.decode().startswith("c")]
            for step, (cable,) in cables[stage].items():
                assert cable.id == "rope"
                assert cable.tension == g["cluster_tension"][step, 0] == g["member_force"][step, rope].max()
                assert [f"rope.{p.node}" for p in cable.pulleys] == pulleys
                np.testing.assert_array_equal([p.slide for p in cable.pulleys], g["pulley_slide"][step])
        assert np.abs(f["pull/pulley_slide"][-1]).max() > 1e-3, "the rope slipped round the drum"
