"""Every command, given bad arguments or paths, ends in one line on stderr and exit 2: never a
traceback, never a file left behind."""
import sys

import pytest

import twin.cli as cli

MISSING = "/nonexistent/folder"


def run(monkeypatch, capsys, args) -> tuple[int, str]:
    monkeypatch.setattr(sys, "argv", ["twin", *map(str, args)])
    with pytest.raises(SystemExit) as exit_info:
        cli.main()
    return exit_info.value.code, capsys.readouterr().err


@pytest.fixture(scope="module")
def paths(tmp_path_factory):
    root = tmp_path_factory.mktemp("bad")
    (root / "folder.csv").mkdir()
    (root / "not_a_log.csv").write_text("hello\n")
    (root / "vessel.json").write_text('{"name": "x"}')
    return root


def cases(root):
    v = ["--vessel", "yellowfish"]
    return [
        ("simulate", "--bogus"),
        ("simulate", *v, "--duration", "abc", "--out", root / "a.csv"),
        ("simulate", *v, "--out", root / "folder.csv"),
        ("simulate", *v, "--out", "/proc/x.rrd"),
        ("simulate", *v, "--out", f"{MISSING}/a.csv"),
        ("simulate", *v, "--out", root / "a.txt"),
        ("simulate", "--vessel", "titanic", "--out", root / "a.csv"),
        ("simulate", "--model", root / "vessel.json", "--out", root / "a.csv"),
        ("simulate", *v, "--out", root / "a.csv", "--origin", "95,10"),
        ("simulate", *v, "--out", root / "a.csv", "--current", "fast,10"),
        ("simulate", *v, "--out", root / "a.csv", "--inputs", root / "missing.csv"),
        ("crosscheck", *v, "--json", f"{MISSING}/c.json"),
        ("params", "--vessel", "titanic"),
        ("validate", *v, "--report", root / "r.pdf"),
        ("info",),
        ("info", root / "not_a_log.csv"),
        ("info", root / "missing.tlog"),
        ("convert", root / "not_a_log.csv", root / "b.mcap"),
        ("convert", root / "missing.csv", root / "b.xyz"),
        ("view", root / "missing.csv"),
        ("view", root / "not_a_log.csv", "--out", root / "folder.csv"),
        ("dataset", *v, "--out", root / "d.txt"),
        ("dataset", *v, "--out", root / "d.tlog", "--effect", "current=fast"),
        ("dataset", *v, "--out", root / "d.tlog", "--segments", "x"),
        ("identify", root / "missing.tlog", *v, "--out", root / "m.json"),
        ("identify", root / "not_a_log.csv", *v, "--out", root / "m.txt"),
        ("identify", root / "not_a_log.csv", *v, "--out", root / "m.json", "--beliefs", "a,b"),
        ("evaluate", *v, root / "missing.tlog"),
        ("evaluate", *v, root / "not_a_log.csv", "--json", root / "folder.csv"),
        ("iso", *v, "--dof", "sway"),
        ("iso", *v, "--amplitudes", "x"),
        ("dp", *v, "--run", "circle"),
        ("diagnose", root / "missing.csv", *v),
        ("diagnose", root / "not_a_log.csv", *v, "--report", root / "r.pdf"),
        ("sitl", *v, "--port", "99999"),
        ("sitl", *v, "--record", root / "s.txt"),
        ("nosuchcommand",),
    ]


def test_every_command_answers_bad_input_with_one_line(monkeypatch, capsys, paths):
    for args in cases(paths):
        code, err = run(monkeypatch, capsys, args)
        assert code == 2, (args, code, err)
        assert err.startswith("error:") and len(err.strip().splitlines()) == 1, (args, err)
        assert "Traceback" not in err
    leftovers = sorted(p.name for p in paths.iterdir() if p.name not in ("folder.csv", "not_a_log.csv",
                                                                          "vessel.json"))
    assert leftovers == [], leftovers


def test_a_bare_twin_prints_its_help_and_is_not_an_error(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["twin"])
    with pytest.raises(SystemExit) as exit_info:
        cli.main()
    assert exit_info.value.code in (0, 2) and "Usage" in capsys.readouterr().out
