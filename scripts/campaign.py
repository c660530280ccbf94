"""The reliability campaign of issue 29, as one measured batch (scripts/campaign runs it).

Phases, each counted: mutated configs through `tsim check`, short runs of the accepted
ones, SIGINT / SIGTERM / SIGKILL at random moments followed by a resume, concurrent runs
into one directory, runs racing `tsim collect`, full disks (tmpfs of 1, 4 and 16 MB, root
only), and a byte flipped in the middle of every output of a complete run. After every
phase each case that says complete is verified: its outcome's CRC-32s match its files,
result.h5 opens and says complete, and no floating-point dataset holds a non-finite value.
At the end the file system is searched for files written outside the campaign's --out
directories since it started.

Prints a table of counts and writes it to WORK/campaign.json. Exit 1 when any count that
must be 0 is not.
"""

import argparse
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
import zlib
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
COUNTS = {
    "check: mutants": 0,
    "check: accepted": 0,
    "check: rejected": 0,
    "check: verdict differs from the library's": 0,
    "runs": 0,
    "runs: interrupted at the time limit": 0,
    "signals: SIGINT": 0,
    "signals: SIGTERM": 0,
    "signals: SIGKILL": 0,
    "signals: resumed result differs from an uninterrupted run": 0,
    "concurrent runs": 0,
    "concurrent: refused (directory held)": 0,
    "collect races": 0,
    "collect: calls during runs": 0,
    "disk full: runs": 0,
    "disk full: temporary files left": 0,
    "byte flips": 0,
    "byte flips: detected (rerun or refused)": 0,
    "byte flips: harmless (the field is not a result)": 0,
    "panics": 0,
    "aborts and other signals": 0,
    "hangs": 0,
    "complete cases verified": 0,
    "non-finite complete": 0,
    "corrupt complete": 0,
    "files written outside --out": 0,
}
MUST_BE_ZERO = [
    "check: verdict differs from the library's",
    "signals: resumed result differs from an uninterrupted run",
    "disk full: temporary files left",
    "panics",
    "aborts and other signals",
    "hangs",
    "non-finite complete",
    "corrupt complete",
    "files written outside --out",
]
FINDINGS = []


def finding(kind, what):
    COUNTS[kind] += 1
    if len(FINDINGS) < 200:
        FINDINGS.append(f"{kind}: {what}")


def tsim(args, cwd, timeout, stop_after=None):
    """Runs tsim; returns (exit code, stderr). A run past `timeout` gets SIGTERM and 20 s
    to end; one that does not end then is a hang (killed)."""
    proc = subprocess.Popen([str(BIN), *args], cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        _, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGTERM)
        try:
            _, err = proc.communicate(timeout=20)
            if stop_after is not None:
                COUNTS[stop_after] += 1
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
            finding("hangs", f"{args}: did not end 20 s after SIGTERM")
    judge(proc.returncode, err, args)
    return proc.returncode, err


def judge(code, err, what):
    """A panic (exit 101 or 'panicked at') or a death by a signal tsim did not get sent."""
    if code == 101 or "panicked at" in (err or ""):
        finding("panics", f"{what}: {(err or '').strip()[-300:]}")
    elif code < 0 and -code not in (signal.SIGKILL, signal.SIGTERM, signal.SIGINT):
        finding("aborts and other signals", f"{what}: signal {-code}")


def crc(path):
    c = 0
    with open(path, "rb") as f:
        while block := f.read(1 << 20):
            c = zlib.crc32(block, c)
    return f"{c:08x}"


def verify_run(run_dir):
    """Every case of `run_dir` whose outcome.json says complete: its files match the
    recorded CRC-32s and lengths, result.h5 opens, says complete, and holds no non-finite
    float. Returns the number verified."""
    n = 0
    for outcome_path in Path(run_dir).glob("*/outcome.json"):
        case = outcome_path.parent
        try:
            outcome = json.loads(outcome_path.read_text())
        except (ValueError, UnicodeDecodeError):
            continue  # not a complete case: tsim reruns it
        if outcome.get("status") != "complete":
            continue
        n += 1
        for name, rec in (outcome.get("files") or {}).items():
            path = case / name
            if not path.exists() or path.stat().st_size != rec["bytes"] or crc(path) != rec["crc32"]:
                finding("corrupt complete", f"{path}: does not match its outcome")
        h5 = case / "result.h5"
        if h5.exists():
            try:
                with h5py.File(h5, "r") as f:
                    if f.attrs.get("status") not in ("complete", b"complete"):
                        finding("corrupt complete", f"{h5}: status {f.attrs.get('status')!r}")
                    bad = []

                    def visit(name, obj):
                        if isinstance(obj, h5py.Dataset) and obj.dtype.kind == "f" and obj.size:
                            if not np.all(np.isfinite(obj[()])):
                                bad.append(name)

                    f.visititems(visit)
                    for name in bad:
                        finding("non-finite complete", f"{h5}: {name}")
            except OSError as e:
                finding("corrupt complete", f"{h5}: cannot be read: {e}")
    COUNTS["complete cases verified"] += n
    return n


def phase_check(work, mutants):
    """Mutants of every shipped config through `tsim check`, against the library's verdict."""
    mdir = work / "mutants"
    shutil.rmtree(mdir, ignore_errors=True)
    mdir.mkdir(parents=True)
    env = dict(os.environ, TSIM_MUTANTS=str(mutants), TSIM_MUTANTS_DIR=str(mdir))
    subprocess.run(
        ["cargo", "test", "--release", "--quiet", "--test", "mutations"], cwd=ROOT, env=env, check=True, stdout=subprocess.DEVNULL
    )
    # The seeds' tables beside their mutants.
    for d in [p for p in mdir.rglob("*") if p.is_dir()]:
        for csv in (ROOT / d.relative_to(mdir)).glob("*.csv"):
            shutil.copy(csv, d)
    files = sorted(mdir.rglob("m*.yaml"))
    for path in files:
        COUNTS["check: mutants"] += 1
        code, err = tsim(["check", path.name, "--out", str(work / "out-check")], cwd=path.parent, timeout=30)
        ok = path.stem.endswith("-ok")
        if code == 0:
            COUNTS["check: accepted"] += 1
        elif code == 2:
            COUNTS["check: rejected"] += 1
        if code in (0, 2) and (code == 0) != ok:
            finding("check: verdict differs from the library's", f"{path}: exit {code}: {err.strip()[:200]}")
    return [p for p in files if p.stem.endswith("-ok")]


def seed_of(mutant):
    """The seed config's stem of a mutant `m<k>-<seed>-<ok|no>.yaml`."""
    return mutant.stem.split("-", 1)[1].rsplit("-", 1)[0]


def phase_runs(work, accepted, count):
    """Short runs of accepted mutants whose seed runs within a few seconds."""
    quick = set()
    for seed in sorted({seed_of(p) for p in accepted}):
        for sub in ["configs", "configs/examples", "tests/fixtures", "tests/corpus"]:
            s = ROOT / sub / f"{seed}.yaml"
            if s.exists():
                t = time.time()
                code, _ = tsim(["run", str(s), "--out", str(work / "out-seeds"), "--quiet", "--jobs", "1"], cwd=work, timeout=8)
                if code == 0 and time.time() - t < 5:
                    quick.add(seed)
    pool = [p for p in accepted if seed_of(p) in quick]
    random.Random(29).shuffle(pool)
    for k, path in enumerate(pool[:count]):
        out = work / "out-runs" / f"r{k:04d}"
        tsim(["run", path.name, "--out", str(out), "--quiet", "--jobs", "1"], cwd=path.parent, timeout=20, stop_after="runs: interrupted at the time limit")
        COUNTS["runs"] += 1
        for run_dir in out.glob("*"):
            verify_run(run_dir)
    return sorted(quick)


def campaign_config(work):
    """A 2 × 2 sweep of the small prism with a deployment of 600 s (every 100th step
    recorded) and a ground-motion table: some 4 s per run, every output kind, a kept table."""
    text = (ROOT / "tests/fixtures/small_sweep.yaml").read_text()
    text = text.replace("deployment:\n  duration: 0.1", "deployment:\n  duration: 600.0")
    text = text.replace("sweep:", "outputs: { every: 100 }\nsweep:", 1)
    text = text.replace(
        "free_vibration:\n  duration: 0.05\n",
        "free_vibration:\n  duration: 0.05\n  ground_motion: { acceleration: [0.5, 0, 0], time: { table: { file: pulse.csv } } }\n",
    )
    d = work / "cfg"
    d.mkdir(parents=True, exist_ok=True)
    shutil.copy(ROOT / "tests/fixtures/ground_pulse.csv", d / "pulse.csv")
    (d / "small.yaml").write_text(text)
    return d / "small.yaml"


def files_of(run_dir):
    return {p.relative_to(run_dir): p.read_bytes() for p in sorted(Path(run_dir).rglob("*")) if p.is_file() and p.name != ".lock"}


def results_of(run_dir):
    """What must not depend on interruptions: each case's case.yaml, result.h5 and replay.mcap."""
    return {k: v for k, v in files_of(run_dir).items() if k.name in ("case.yaml", "result.h5", "replay.mcap")}


def phase_signals(work, cfg, reference, n):
    rng = random.Random(2029)
    plan = [("SIGINT", signal.SIGINT)] * n + [("SIGTERM", signal.SIGTERM)] * n + [("SIGKILL", signal.SIGKILL)] * (n // 2)
    for k, (name, sig) in enumerate(plan):
        out = work / "out-signals" / f"s{k:02d}"
        proc = subprocess.Popen(
            [str(BIN), "run", str(cfg), "--out", str(out), "--quiet", "--jobs", "2"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
        )
        time.sleep(rng.uniform(0.05, 3.5))
        proc.send_signal(sig)
        if sig != signal.SIGKILL and k % 2:
            time.sleep(0.005)  # a second signal a few ms after the first
            proc.send_signal(sig)
        try:
            _, err = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
            finding("hangs", f"{name} {k}: did not end in 30 s")
        judge(proc.returncode, err, f"{name} {k}")
        COUNTS[f"signals: {name}"] += 1
        run_dir = out / "small"
        verify_run(run_dir)
        # The resume completes every case, with the uninterrupted run's results.
        code, err = tsim(["run", str(cfg), "--out", str(out), "--quiet", "--jobs", "2"], cwd=work, timeout=120)
        verify_run(run_dir)
        if code != 0 or results_of(run_dir) != reference:
            differ = sorted(str(p) for p in set(results_of(run_dir)) ^ set(reference)) or [
                str(p) for p, b in results_of(run_dir).items() if reference.get(p) != b
            ]
            finding("signals: resumed result differs from an uninterrupted run", f"{name} {k}: exit {code}, {differ[:4]} {err.strip()[-200:]}")


def phase_concurrent(work, cfg):
    out = work / "out-concurrent"
    procs = [
        subprocess.Popen([str(BIN), "run", str(cfg), "--out", str(out), "--quiet", "--jobs", "1"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        for _ in range(10)
    ]
    for p in procs:
        try:
            _, err = p.communicate(timeout=300)
        except subprocess.TimeoutExpired:
            p.kill()
            _, err = p.communicate()
            finding("hangs", "a concurrent run did not end in 300 s")
        judge(p.returncode, err, "concurrent run")
        COUNTS["concurrent runs"] += 1
        if p.returncode == 2 and "in use" in err:
            COUNTS["concurrent: refused (directory held)"] += 1
    verify_run(out / "small")


def phase_collect_races(work, cfg):
    out = work / "out-collect"
    tsim(["run", str(cfg), "--out", str(out), "--quiet"], cwd=work, timeout=120)
    for _ in range(10):
        run = subprocess.Popen([str(BIN), "run", str(cfg), "--out", str(out), "--quiet", "--force"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        while run.poll() is None:
            code, _ = tsim(["collect", str(out / "small")], cwd=work, timeout=60)
            COUNTS["collect: calls during runs"] += 1
            if code not in (0, 1, 2):
                finding("aborts and other signals", f"collect exit {code}")
            time.sleep(0.05)
        judge(run.returncode, run.stderr.read(), "run racing collect")
        COUNTS["collect races"] += 1
        verify_run(out / "small")
        if run.returncode != 0:
            finding("corrupt complete", f"a run racing collect exited {run.returncode}")
    code, err = tsim(["collect", str(out / "small")], cwd=work, timeout=60)
    if code != 0:
        finding("corrupt complete", f"collect after the races: exit {code}: {err.strip()[-200:]}")


def phase_disk_full(work):
    if os.geteuid() != 0:
        print("disk full: skipped (needs root for tmpfs mounts)")
        return
    for mb in (1, 4, 16):
        mnt = work / f"full{mb}"
        mnt.mkdir(exist_ok=True)
        if subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={mb}m", "tmpfs", str(mnt)]).returncode != 0:
            print(f"disk full {mb} MB: skipped (mount failed)")
            continue
        try:
            code, err = tsim(["run", str(ROOT / "configs/paper.yaml"), "--out", str(mnt), "--quiet"], cwd=work, timeout=300)
            COUNTS["disk full: runs"] += 1
            left = [p for p in mnt.rglob("*") if p.name.endswith((".tmp", ".new")) or ".partial" in p.name]
            for p in left:
                finding("disk full: temporary files left", str(p))
            for run_dir in mnt.glob("*"):
                verify_run(run_dir)
            print(f"disk full {mb} MB: exit {code}: {err.strip().splitlines()[-1] if err.strip() else ''}"[:300])
        finally:
            subprocess.run(["umount", str(mnt)])


def reran(err):
    """The cases a run computed, from its last line ("… (C computed, R reused) …")."""
    m = re.search(r"\((\d+) computed, (\d+) reused\)", err or "")
    return int(m.group(1)) if m else -1


def phase_byte_flips(work, cfg):
    """A byte flipped in the middle of every file of a complete run. A case's file must make
    the resume recompute that case (and `tsim collect` refuse it first, for its outputs);
    a run-level file (summaries, collected.h5, a kept table) must be rewritten."""
    base = work / "out-flips-base"
    tsim(["run", str(cfg), "--out", str(base), "--quiet"], cwd=work, timeout=120)
    run_dir = base / "small"
    targets = [p.relative_to(run_dir) for p in sorted(run_dir.rglob("*")) if p.is_file() and p.name != ".lock"]
    for k, rel in enumerate(targets):
        trial = work / "out-flips" / f"f{k:03d}"
        shutil.rmtree(trial, ignore_errors=True)
        shutil.copytree(base, trial)
        path = trial / "small" / rel
        data = bytearray(path.read_bytes())
        if not data:
            continue
        at = len(data) // 2
        data[at] ^= 0xFF
        path.write_bytes(bytes(data))
        flipped = bytes(data)
        COUNTS["byte flips"] += 1
        case_file = len(rel.parts) == 2 and rel.parts[0] != "tables"
        if rel.name in ("result.h5", "replay.mcap"):
            code, _ = tsim(["collect", str(trial / "small")], cwd=work, timeout=60)
            if code == 0:
                finding("corrupt complete", f"collect served {rel} flipped at byte {at} as complete")
        code, err = tsim(["run", str(cfg), "--out", str(trial), "--quiet"], cwd=work, timeout=120)
        verify_run(trial / "small")
        after = files_of(trial / "small")
        if results_of(trial / "small") != results_of(run_dir):
            finding("corrupt complete", f"{rel} flipped at byte {at}: the resumed run's results differ from the original's (exit {code})")
        elif case_file and reran(err) >= 1:
            COUNTS["byte flips: detected (rerun or refused)"] += 1
        elif not case_file and after.get(rel) != flipped:
            COUNTS["byte flips: detected (rerun or refused)"] += 1
        elif case_file and rel.name == "outcome.json":
            # Reused: the flip left the outcome readable and its checksums matching (a
            # wall time, a figure's text); the results are the original's (checked above).
            COUNTS["byte flips: harmless (the field is not a result)"] += 1
            FINDINGS.append(f"byte flip in {rel} at {at}: reused; {flipped[at-20:at+20]!r}")
        else:
            finding("corrupt complete", f"{rel} flipped at byte {at}: kept as it was ({reran(err)} computed)")


def outside_writes(work, marker):
    """Files changed since `marker` anywhere on this file system but the campaign's
    directory and the build's."""
    # Besides the system's own logs, caches and state: the state files of the test Slurm
    # cluster scripts/test starts (its slurmctld writes them every few minutes).
    skip = [str(work), "/proc", "/sys", "/dev", "/run", str(ROOT / "target"), "/tmp/target", "/root/.cargo", "/var/log", "/var/cache",
            "/var/lib", "/var/spool/tsim-slurm"]
    cmd = ["find", "/", "-xdev"]
    for s in skip:
        cmd += ["-path", s, "-prune", "-o"]
    cmd += ["-newer", str(marker), "-type", "f", "-print"]
    found = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True).stdout.splitlines()
    # Outside /tmp, /work and the home directory nothing may change; inside them (where
    # other work goes on) no file of the kinds tsim writes.
    names = ("case.yaml", "result.h5", "replay.mcap", "outcome.json", "summary.csv", "summary.json", "collected.h5", "plan.json")
    ours = lambda f: Path(f).name in names or f.endswith((".tmp", ".new", ".partial", ".lock")) or "/tables/" in f or "/shards/" in f
    return [f for f in found if ours(f) or not f.startswith(("/tmp/", "/work/", "/root/"))]


def main():
    global BIN
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", default="/tmp/tsim-campaign")
    ap.add_argument("--mutants", type=int, default=3000)
    ap.add_argument("--runs", type=int, default=300)
    ap.add_argument("--signals", type=int, default=20, help="SIGINTs and SIGTERMs each (half as many SIGKILLs)")
    ap.add_argument("--bin", default=str(ROOT / "target/release/tsim"))
    args = ap.parse_args()
    BIN = Path(args.bin).resolve()
    work = Path(args.work)
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    marker = work / "started"
    marker.touch()
    time.sleep(1.1)
    started = time.time()
    walls = {}

    def timed(name, f, *a):
        t = time.time()
        r = f(*a)
        walls[name] = round(time.time() - t, 1)
        print(f"{name}: {walls[name]} s", flush=True)
        return r

    accepted = timed("check", phase_check, work, args.mutants)
    quick = timed("runs", phase_runs, work, accepted, args.runs)
    cfg = campaign_config(work)
    ref = work / "out-reference"
    tsim(["run", str(cfg), "--out", str(ref), "--quiet", "--jobs", "2"], cwd=work, timeout=120)
    verify_run(ref / "small")
    reference = results_of(ref / "small")
    timed("signals", phase_signals, work, cfg, reference, args.signals)
    timed("concurrent", phase_concurrent, work, cfg)
    timed("collect races", phase_collect_races, work, cfg)
    timed("disk full", phase_disk_full, work)
    timed("byte flips", phase_byte_flips, work, cfg)
    outside = outside_writes(work, marker)
    for f in outside:
        finding("files written outside --out", f)
    report = {"counts": COUNTS, "seconds": walls, "total_seconds": round(time.time() - started, 1), "quick_seeds": quick, "findings": FINDINGS}
    (work / "campaign.json").write_text(json.dumps(report, indent=1))
    width = max(map(len, COUNTS))
    for k, v in COUNTS.items():
        print(f"{k:{width}}  {v}")
    for f in FINDINGS[:60]:
        print("  " + f)
    bad = [k for k in MUST_BE_ZERO if COUNTS[k]]
    print(f"total {report['total_seconds']} s; " + (f"NOT ZERO: {', '.join(bad)}" if bad else "every must-be-zero count is 0"))
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
