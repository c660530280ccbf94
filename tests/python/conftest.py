"""Shared fixtures of the Python tests (run from the repository root: .venv/bin/pytest tests/python)."""

import json
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def tsim_bin():
    """The release `tsim` binary, built once per session (cargo decides if it is fresh)."""
    subprocess.run(["cargo", "build", "--release", "--quiet", "--bin", "tsim"], cwd=ROOT, check=True)
    meta = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps"],
        cwd=ROOT, check=True, capture_output=True, text=True,
    )
    return Path(json.loads(meta.stdout)["target_directory"]) / "release" / "tsim"


@pytest.fixture(scope="session")
def wheel():
    """The Python package's wheel (python/), built or refreshed by scripts/wheel."""
    subprocess.run([ROOT / "scripts" / "wheel", "--quiet"], check=True, cwd=ROOT)
    wheels = sorted((ROOT / "target" / "wheels").glob("tsim-*-abi3-*.whl"), key=lambda p: p.stat().st_mtime)
    assert wheels, "scripts/wheel wrote no abi3 wheel into target/wheels"
    return wheels[-1]
