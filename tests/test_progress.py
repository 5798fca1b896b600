"""Progress on long work: package functions tell a callback what they do, k of n; the command
line shows it as a bar only on a terminal and never with --quiet."""
import os
import re
import subprocess
import sys

import pytest

from twin.cli import app as cli_app
from twin.engine.mjcf import compile_vessel
from twin.ident.relay import iso
from twin.synth.dataset import PROFILES, generate
from twin.vessel import load


class Heard:
    """A progress callback that remembers every call."""

    def __init__(self):
        self.calls = []

    def __call__(self, what, done=None, total=None):
        self.calls.append((what, done, total))


def test_dataset_reports_each_segment_k_of_n():
    heard = Heard()
    # seeded: the plan of manoeuvres (open- and closed-loop segments) follows from the seed
    ds = generate(load("yellowfish"), n_segments=4, manoeuvres=["rc", "zigzag"], seed=3, noise=PROFILES["none"],
                  segment_s=(15.0, 20.0), progress=heard)
    assert len(ds.runs) == 4
    totals = {total for _, _, total in heard.calls}
    assert totals == {4}
    logged = [(what, done) for what, done, _ in heard.calls if what.startswith("logging")]
    assert [done for _, done in logged] == [0, 1, 2, 3]
    assert logged[2][0].startswith("logging segment 3 of 4")
    simulated = [done for what, done, _ in heard.calls if what.startswith("simulating")]
    assert simulated == sorted(simulated) and simulated[0] == 0 and max(simulated) <= 3
    # the zig-zags (segments 2 and 4) are closed loop: each is reported by its number
    assert any(what.startswith("simulating segment 2 of 4 (zigzag") for what, _, _ in heard.calls)
    assert any(what.startswith("simulating segment 4 of 4 (zigzag") for what, _, _ in heard.calls)


def test_dataset_without_progress_is_the_same_dataset():
    kwargs = dict(n_segments=2, manoeuvres=["rc"], seed=5, noise=PROFILES["realistic"], segment_s=(15.0, 16.0))
    a = generate(load("yellowfish"), **kwargs)
    b = generate(load("yellowfish"), progress=Heard(), **kwargs)
    assert (a.recording.gnss.t == b.recording.gnss.t).all()
    assert (a.recording.gnss.columns["lat_deg"] == b.recording.gnss.columns["lat_deg"]).all()


def test_iso_sweep_reports_each_relay_run():
    heard = Heard()
    result = iso.sweep(compile_vessel(load("yellowfish")), "yaw", [2.0, 3.0], duration_s=12.0, progress=heard)
    assert len(result.rows) == 2
    assert [(done, total) for _, done, total in heard.calls] == [(0, 2), (1, 2), (2, 2)]
    assert "±2 N·m" in heard.calls[0][0] and "±3 N·m" in heard.calls[1][0]


@pytest.mark.parametrize("quiet, tty", [(True, True), (False, False), (True, False)])
def test_progress_bar_is_silent_when_quiet_or_off_a_terminal(monkeypatch, capsys, quiet, tty):
    monkeypatch.setitem(cli_app._settings, "quiet", quiet)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: tty)
    with cli_app.progress_bar("test") as progress:
        for k in range(3):
            progress(f"step {k + 1} of 3", k, 3)
    out = capsys.readouterr()
    assert out.out == "" and out.err == ""


def _on_a_terminal(args: list[str]) -> str:
    """stderr of `twin ARGS` run with a pseudo-terminal as its stderr, without terminal escapes."""
    import pty

    leader, follower = pty.openpty()
    env = {**os.environ, "COLUMNS": "160", "TERM": "xterm"}
    proc = subprocess.Popen([sys.executable, "-m", "twin", *args], stdout=subprocess.DEVNULL, stderr=follower,
                            stdin=subprocess.DEVNULL, env=env)
    os.close(follower)
    chunks = []
    while True:  # read until the child closes its end (EIO on Linux)
        try:
            data = os.read(leader, 65536)
        except OSError:
            break
        if not data:
            break
        chunks.append(data)
    os.close(leader)
    assert proc.wait(timeout=120) == 0
    return re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", b"".join(chunks).decode("utf-8", "replace"))  # colours, cursor


ISO = ["iso", "--vessel", "yellowfish", "--amplitudes", "2,3", "--duration", "30"]  # each run > a redraw (0.1 s)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pseudo-terminal reading as on Linux")
def test_cli_bar_on_a_terminal_and_not_with_quiet():
    # the bar redraws ten times a second, so a quick middle step may never be drawn: the first
    # (the engine compiles then) and the last are
    shown = _on_a_terminal(ISO)
    assert "0/2 IS-O yaw: relay ±2 N·m" in shown and "2/2 IS-O yaw: done" in shown
    hidden = _on_a_terminal(["--quiet", *ISO])
    assert "IS-O" not in hidden and "2/2" not in hidden
