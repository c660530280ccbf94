"""Runs from Python, models from NumPy arrays, results as xarray and pandas objects."""

import json
import os
import sys
import warnings
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from . import _tsim
from ._tsim import ConfigError

# The name a dict config goes by in error messages; having no directory, its relative
# paths (time tables) start from the current directory.
DICT_ORIGIN = "<dict config>"

AXES = "xyz"


def run(config, out="runs", *, jobs=None, force=False, only=(), allow_large=False, quiet=True):
    """Run every case of `config` into `out/<name>/`, as `tsim run` does; a `Run`.

    `config` is a YAML file's path or a dict of the same keys (docs/config.md; NumPy
    arrays and scalars are taken as lists and numbers, `tsim.model` builds its `model`).
    `jobs`, `force`, `only` (case-id patterns), `allow_large` are `tsim run`'s options;
    `quiet=False` draws the progress bars on the terminal's stderr.

    A config that does not load raises `tsim.ConfigError` with every bad value; a case
    that fails fails alone (`Run.failed` says why, with a warning); Ctrl-C (or a
    notebook's stop) stops the running cases at their next step, closes their files as
    interrupted and raises KeyboardInterrupt. Complete cases of an earlier run with the
    same config are reused, as by `tsim run`.
    """
    if isinstance(only, str):
        only = [only]
    # `outputs.figures` draws with TSIM_PYTHON: this interpreter, unless the user named another.
    os.environ.setdefault("TSIM_PYTHON", sys.executable)
    if jobs is not None and (isinstance(jobs, bool) or int(jobs) != jobs or jobs < 1):
        raise ValueError(f"jobs={jobs!r}: give a whole number >= 1, or None for one per core")
    options = dict(
        jobs=None if jobs is None else int(jobs),
        force=force,
        quiet=quiet,
        only=list(only),
        allow_large=allow_large,
    )
    if isinstance(config, Mapping):
        text = json.dumps(config, default=_plain, allow_nan=False, indent=1)
        directory, outcomes = _tsim.run_config(DICT_ORIGIN, os.fspath(out), text=text, **options)
    else:
        directory, outcomes = _tsim.run_config(os.fspath(config), os.fspath(out), **options)
    result = Run(directory, json.loads(outcomes))
    for case, reason in result.failed.items():
        warnings.warn(f"tsim: case {case} failed: {reason}", RuntimeWarning, stacklevel=2)
    return result


def _plain(value):
    """A value json cannot write, as the plain one the config means."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, (set, frozenset)):
        return sorted(value)
    raise TypeError(f"{type(value).__name__} {value!r} has no place in a tsim config")


class Run:
    """A run directory (`out/<name>/`) and its cases' outcomes.

    Results are read from the files the run wrote (docs/outputs.md), loaded into memory
    (the files are closed again, so a later run may replace them); `lazy=True` opens
    them instead, for results larger than memory.
    """

    def __init__(self, directory, outcomes):
        self.directory = Path(directory)
        #: One record per case, as in summary.json: id, params, status, reason, summary, ...
        self.outcomes = outcomes

    def __repr__(self):
        states = {}
        for o in self.outcomes:
            states[o["status"]] = states.get(o["status"], 0) + 1
        counts = ", ".join(f"{n} {s}" for s, n in sorted(states.items()))
        return f"<tsim.Run {self.directory} ({counts})>"

    @property
    def cases(self):
        """The case ids, in the sweep's order."""
        return [o["id"] for o in self.outcomes]

    @property
    def failed(self):
        """The failed cases' ids and reasons."""
        return {o["id"]: o.get("reason") for o in self.outcomes if o["status"] == "failed"}

    def summary(self):
        """summary.csv as a pandas DataFrame: a row per case, its parameters and figures."""
        import pandas as pd

        return pd.read_csv(self.directory / "summary.csv")

    def collected(self, lazy=False):
        """collected.h5 as an xarray Dataset: the cases along `case`, the swept parameters
        as coordinates; energies, positions and member forces per stage."""
        return _dataset(self.directory / "collected.h5", None, lazy)

    def path(self, case=None, name="result.h5"):
        """The path of a case's file (`result.h5`, `replay.mcap`, `paraview/<stage>.vtkhdf`)."""
        return self.directory / self._case(case) / name

    def result(self, case=None, stage=None, lazy=False):
        """A group of a case's result.h5 as an xarray Dataset: a stage's by its name,
        `"model"`, or with `stage` None the root (its attributes: status, config, sweep
        parameters). `case` may be left out when the run has one case."""
        return _dataset(self.path(case), stage, lazy)

    def figures(self, case=None, options=()):
        """Draw a case's figures (`case` None: the only case, or the sweep's overview of
        several) as `tsim figures` does, with this interpreter; their folder. `options` are
        the command's (`["--svg"]`, `["--dpi", "60"]`, `["--only", "structure"]`;
        docs/figures.md). Needs matplotlib: `pip install "tsim[figures]"`."""
        options = [str(o) for o in options]
        path = self.directory if case is None and len(self.outcomes) > 1 else self.directory / self._case(case)
        os.environ.setdefault("TSIM_PYTHON", sys.executable)
        code = _tsim.cli(["tsim", "figures", os.fspath(path), *options])
        if code != 0:
            raise RuntimeError(f"tsim figures {path} exited {code}: its messages are on standard error")
        out = options[options.index("--out") + 1] if "--out" in options else path / "figures"
        return Path(out)

    def _case(self, case):
        if case is None:
            if len(self.outcomes) != 1:
                raise ValueError(f"name the case: this run has {len(self.outcomes)}, e.g. {self.cases[:3]}")
            return self.outcomes[0]["id"]
        if case not in self.cases:
            raise KeyError(f"no case {case!r} in {self.directory}; the cases: {self.cases[:5]}...")
        return case


def _dataset(path, group, lazy):
    import xarray as xr

    opener = xr.open_dataset if lazy else xr.load_dataset
    return opener(path, engine="h5netcdf", group=group)


def model(nodes, members, kind, *, node_ids=None, member_ids=None, fix=None, rest_length=None, member_groups=None, node_groups=None, clusters=None):
    """The `model` section of a config from arrays.

    nodes: (n, 3) coordinates [m]. members: (m, 2) node indices (from 0) of each member's
    ends. kind: "strut" or "cable", one for all or one per member. node_ids, member_ids:
    names (default n0, n1, ... and s<i> for a strut, c<i> for a cable, i the member's
    index). fix: the supported directions, a (n, 3) boolean array or a mapping from a node
    (index or id) to its directions ("xz"). rest_length: (m,) [m], for a model run without
    form-finding (NaN: none). member_groups: a mapping from a group name to its members
    (indices or ids). node_groups: the same for nodes (point masses, loads, initial
    conditions). clusters: a mapping from a clustered cable's id to its members (indices
    or ids) in the order the cable runs through them, or to {"members": ..., "friction":
    μ} for capstan friction over its pulleys (docs/config.md, "Clustered cables").
    """
    x = np.asarray(nodes, dtype=float)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"nodes: an (n, 3) array of coordinates, not shape {x.shape}")
    ends = np.asarray(members)
    if ends.ndim != 2 or ends.shape[1] != 2 or not np.issubdtype(ends.dtype, np.integer):
        raise ValueError(f"members: an (m, 2) array of node indices, not {ends.dtype} of shape {ends.shape}")
    n, m = len(x), len(ends)
    if m and (ends.min() < 0 or ends.max() >= n):
        bad = int(np.flatnonzero((ends < 0).any(1) | (ends >= n).any(1))[0])
        raise ValueError(f"members[{bad}] = {ends[bad].tolist()}: node indices run from 0 to {n - 1}")
    kinds = [kind] * m if isinstance(kind, str) else list(kind)
    if len(kinds) != m or any(k not in ("strut", "cable") for k in kinds):
        raise ValueError('kind: "strut" or "cable", one for all members or one per member')
    node_ids = _names(node_ids, [f"n{i}" for i in range(n)], "node_ids")
    member_ids = _names(member_ids, [f"{k[0]}{i}" for i, k in enumerate(kinds)], "member_ids")
    fixed = _fixed(fix, node_ids)
    node_list = []
    for i, name in enumerate(node_ids):
        node = {"id": name, "xyz": x[i].tolist()}
        if fixed[i]:
            node["fix"] = fixed[i]
        node_list.append(node)
    lengths = None if rest_length is None else np.broadcast_to(np.asarray(rest_length, dtype=float), (m,))
    groups_of = _groups_of(member_groups, member_ids, "member_groups")
    member_list = []
    for j, name in enumerate(member_ids):
        member = {"id": name, "nodes": [node_ids[ends[j, 0]], node_ids[ends[j, 1]]], "kind": kinds[j]}
        if groups_of[j]:
            member["groups"] = groups_of[j]
        if lengths is not None and np.isfinite(lengths[j]):
            member["rest_length"] = float(lengths[j])
        member_list.append(member)
    section = {"nodes": node_list, "members": member_list}
    if node_groups:
        section["groups"] = {g: [node_ids[i] for i in _indices(v, node_ids, f"node_groups[{g!r}]")] for g, v in node_groups.items()}
    if clusters:
        section["clusters"] = [_cluster(c, v, member_ids) for c, v in clusters.items()]
    return section


def _cluster(name, given, member_ids):
    """One `model.clusters` entry from a member list or {"members", "friction"}."""
    spec = dict(given) if isinstance(given, dict) else {"members": given}
    unknown = set(spec) - {"members", "friction"}
    if unknown or "members" not in spec:
        raise ValueError(f"clusters[{name!r}]: a member list or {{'members': [...], 'friction': mu}}, not keys {sorted(spec)}")
    entry = {"id": name, "members": [member_ids[j] for j in _indices(spec["members"], member_ids, f"clusters[{name!r}]")]}
    if "friction" in spec:
        entry["friction"] = float(spec["friction"])
    return entry


def _names(given, default, what):
    if given is None:
        return default
    names = [str(s) for s in given]
    if len(names) != len(default):
        raise ValueError(f"{what}: {len(names)} names for {len(default)} items")
    if len(set(names)) != len(names):
        raise ValueError(f"{what}: names repeat")
    return names


def _indices(items, ids, what):
    """Indices of `items`, each an index or an id of `ids`."""
    where = {name: i for i, name in enumerate(ids)}
    out = []
    for item in np.atleast_1d(items).tolist():
        if isinstance(item, str):
            if item not in where:
                raise ValueError(f"{what}: no {item!r} among {ids[:5]}...")
            out.append(where[item])
        elif isinstance(item, int) and 0 <= item < len(ids):
            out.append(item)
        else:
            raise ValueError(f"{what}: {item!r} is neither an id nor an index from 0 to {len(ids) - 1}")
    return out


def _fixed(fix, node_ids):
    """Each node's supported directions, as lists of "x", "y", "z"."""
    fixed = [[] for _ in node_ids]
    if fix is None:
        return fixed
    if isinstance(fix, Mapping):
        for node, directions in fix.items():
            if any(d not in AXES for d in directions):
                raise ValueError(f"fix[{node!r}] = {directions!r}: directions among x, y, z")
            (i,) = _indices([node], node_ids, "fix")
            fixed[i] = [d for d in AXES if d in directions]
        return fixed
    mask = np.asarray(fix, dtype=bool)
    if mask.shape != (len(node_ids), 3):
        raise ValueError(f"fix: a mapping or an (n, 3) boolean array, not shape {mask.shape}")
    return [[AXES[k] for k in range(3) if row[k]] for row in mask]


def _groups_of(groups, ids, what):
    """Each item's group names, from a mapping of group name to items."""
    of = [[] for _ in ids]
    for name, items in (groups or {}).items():
        for i in _indices(items, ids, f"{what}[{name!r}]"):
            of[i].append(name)
    return of
