"""A benchmark of this checkout paired with the same benchmark of an earlier commit, in one run,
alternating, so that a machine's slow hour falls on both alike.

    python scripts/bench_pair.py --before COMMIT [--bench identify,diagnose] [--rounds 2] [--out docs/results]

The earlier commit is checked out into a temporary git worktree (removed afterwards); each round
runs every benchmark once in each tree (scripts/bench_identify.py, scripts/bench_diagnose.py,
each in a fresh process that imports its own tree's package), after one untimed warm-up per tree
(numba's compiled callbacks are cached per tree). Writes docs/results/bench_pair.md and .json:
each run's seconds, the median per tree and their ratio.
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from twin.viz.pages import ResultPage, ResultTable  # noqa: E402

SECONDS_KEY = {"identify": "best_s", "diagnose": "seconds"}


def run_bench(tree: Path, bench: str) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench.json"
        subprocess.run([sys.executable, str(tree / "scripts" / f"bench_{bench}.py"), "--json", str(out)], cwd=tree,
                       check=True, capture_output=True, text=True)
        data = json.loads(out.read_text())
    return float(data[SECONDS_KEY[bench]])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", required=True, help="the commit to pair with (any git revision)")
    ap.add_argument("--bench", default="identify,diagnose")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results")
    args = ap.parse_args()
    benches = [b.strip() for b in args.bench.split(",") if b.strip()]
    unknown = [b for b in benches if b not in SECONDS_KEY]
    if unknown or args.rounds < 1:
        print(f"error: benchmarks are {', '.join(SECONDS_KEY)} and rounds at least 1", file=sys.stderr)
        return 2
    sha = subprocess.run(["git", "rev-parse", "--short", args.before], cwd=ROOT, capture_output=True, text=True)
    if sha.returncode:
        print(f"error: no commit {args.before!r} in this repository", file=sys.stderr)
        return 2
    before = sha.stdout.strip()
    times: dict[str, dict[str, list[float]]] = {b: {"before": [], "after": []} for b in benches}
    with tempfile.TemporaryDirectory() as tmp:
        old = Path(tmp) / "before"
        subprocess.run(["git", "worktree", "add", "--detach", str(old), before], cwd=ROOT, check=True,
                       capture_output=True)
        shared = ROOT.parent / "shared"
        if shared.exists():  # the benchmarks read ../shared beside their checkout
            (Path(tmp) / "shared").symlink_to(shared)
        try:
            for tree in (old, ROOT):  # warm-up: numba compiles and caches each tree's callbacks once
                for b in benches:
                    run_bench(tree, b)
            for k in range(args.rounds):
                for b in benches:
                    for label, tree in (("before", old), ("after", ROOT)) if k % 2 == 0 else \
                            (("after", ROOT), ("before", old)):
                        times[b][label].append(run_bench(tree, b))
                        print(f"round {k + 1} {b} {label}: {times[b][label][-1]:.1f} s", flush=True)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(old)], cwd=ROOT, capture_output=True)
    rows = []
    for b in benches:
        mb, ma = statistics.median(times[b]["before"]), statistics.median(times[b]["after"])
        rows.append([b, ", ".join(f"{x:.1f}" for x in times[b]["before"]), ", ".join(f"{x:.1f}" for x in
                                                                                    times[b]["after"]), mb, ma,
                     ma / mb])
    page = ResultPage(
        name="bench_pair", title="Benchmarks paired with an earlier commit",
        ran=f"python scripts/bench_pair.py --before {before} --bench {','.join(benches)} --rounds {args.rounds}",
        data="scripts/bench_identify.py (the ten shared BlueBoat runs [BlueBoat-SI]) and scripts/bench_diagnose.py "
             "(a 30-minute synthetic recording)",
        summary=f"Each benchmark run in a fresh process in this checkout and in commit `{before}`, alternating "
                "within each round, after one untimed warm-up per tree.",
        tables=[ResultTable("Seconds per run", ["benchmark", f"{before} (s)", "this checkout (s)", "median before",
                                                "median after", "after / before"], rows)],
        raw={"before": before, "times": times})
    print(f"wrote {page.write(args.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
