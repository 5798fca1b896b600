"""The test suite's wall time as CI sees it: a clean clone of this checkout's HEAD, `.ci/run` (a fresh
virtual environment, the install, the README's test command), timed.

    python scripts/bench_suite.py [--rounds 1] [--out docs/results]

The clone gets ../shared beside it when this checkout has it (the tests that read the shared
recordings run, as in CI). Uncommitted changes are not measured: the clone is of HEAD. Writes
docs/results/bench_suite.md and .json: per run the tests passed, skipped and failed, pytest's own
seconds and the seconds with the install, against the target of 8 minutes on the machine's cores.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from twin.viz.pages import ResultPage, ResultTable  # noqa: E402

TARGET_S = 480.0  # 8 minutes of pytest on 2 cores
SUMMARY = re.compile(r"^=*\s*(?P<body>.*\d+ passed.*) in (?P<secs>[\d.]+)s", re.M)


def counts(summary: str) -> dict[str, int]:
    """pytest's summary line ("1130 passed, 3 skipped in 480.1s") as counts by outcome."""
    return {word: int(n) for n, word in re.findall(r"(\d+) (passed|skipped|failed|errors?|xfailed|xpassed)", summary)}


def one_run(shared: Path | None) -> dict:
    """A clean clone of HEAD, `.ci/run` in it: the exit code, pytest's seconds, the whole run's."""
    with tempfile.TemporaryDirectory() as tmp:
        clone = Path(tmp) / "asv"
        subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
        if shared is not None:
            (Path(tmp) / "shared").symlink_to(shared)
        started = time.monotonic()
        done = subprocess.run(["bash", ".ci/run"], cwd=clone, capture_output=True, text=True)
        whole = time.monotonic() - started
    found = list(SUMMARY.finditer(done.stdout))
    if not found:
        tail = (done.stdout + done.stderr).strip().splitlines()[-1:] or ["no output"]
        return {"returncode": done.returncode, "pytest_s": None, "whole_s": round(whole, 1), "counts": {},
                "summary": tail[0]}
    last = found[-1]
    return {"returncode": done.returncode, "pytest_s": float(last["secs"]), "whole_s": round(whole, 1),
            "counts": counts(last["body"]), "summary": last["body"].strip()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results")
    args = ap.parse_args()
    if args.rounds < 1:
        print("error: --rounds must be at least 1", file=sys.stderr)
        return 2
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    if head.returncode:
        print("error: this checkout is not a git repository (the suite is timed on a clone of HEAD)", file=sys.stderr)
        return 2
    shared = ROOT.parent / "shared"
    runs = []
    for k in range(args.rounds):
        runs.append(one_run(shared if shared.exists() else None))
        print(f"run {k + 1}: {runs[-1]['summary']} (exit {runs[-1]['returncode']}), pytest {runs[-1]['pytest_s']} s, "
              f"with the install {runs[-1]['whole_s']} s", flush=True)
    rows = [[k + 1, r["counts"].get("passed", 0), r["counts"].get("skipped", 0),
             r["counts"].get("failed", 0) + r["counts"].get("error", 0) + r["counts"].get("errors", 0),
             r["pytest_s"] if r["pytest_s"] is not None else "-", r["whole_s"],
             "yes" if r["pytest_s"] is not None and r["pytest_s"] <= TARGET_S and r["returncode"] == 0 else "no"]
            for k, r in enumerate(runs)]
    timed = [r["pytest_s"] for r in runs if r["pytest_s"] is not None]
    summary = (f"{len(runs)} run(s) of `.ci/run` on a clean clone of `{head.stdout.strip()}` on {os.cpu_count()} "
               f"cores: pytest took {', '.join(f'{s:.0f}' for s in timed) or 'no'} s against the target of "
               f"{TARGET_S:.0f} s (8 minutes); under it in {sum(r[-1] == 'yes' for r in rows)} of {len(runs)}.")
    page = ResultPage(
        name="bench_suite", title="The test suite's time in CI",
        ran=f"python scripts/bench_suite.py --rounds {args.rounds}",
        data="the project's test suite (`python -m pytest`, pytest-xdist over the machine's cores), with the shared "
             "recordings beside the clone" if shared.exists() else "the project's test suite, without ../shared "
             "(the tests that read it skip)",
        summary=summary,
        tables=[ResultTable("Runs", ["run", "passed", "skipped", "failed", "pytest (s)", "with the install (s)",
                                     "under 8 min"], rows)],
        raw={"head": head.stdout.strip(), "cores": os.cpu_count(), "target_s": TARGET_S, "runs": runs})
    print(f"wrote {page.write(args.out)}")
    return 0 if all(r["returncode"] == 0 for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
