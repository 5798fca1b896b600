"""What a user meets first in the command: the help, and one line and exit 2 for each input that
cannot be meant (tests/test_cli_errors.py has the rest)."""
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import twin_command

ROOT = Path(__file__).resolve().parent.parent


def twin(*args, cwd=None):
    return twin_command.twin(*args, cwd=cwd, env={**os.environ, "COLUMNS": "120"})


def test_help_lists_commands_in_workflow_order_with_one_line_each_and_no_type_tags():
    from twin.cli.app import WORKFLOW

    done = twin("--help")
    assert done.returncode == 0
    listed = [line.split()[1] for line in done.stdout.splitlines()
              if line.startswith("│ ") and len(line.split()) > 2 and line.split()[1] in WORKFLOW]
    assert listed == list(WORKFLOW)
    assert "<bool>" not in done.stdout
    ident = twin("identify", "--help").stdout
    assert "<bool>" not in ident and "<str>" not in ident and "<float>" not in ident


def test_quiet_is_accepted_after_the_command(tmp_path):
    done = twin("simulate", "--vessel", "blueboat", "--duration", "2", "--out", tmp_path / "a.csv", "--quiet")
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""


def test_quiet_holds_for_its_own_run_only(tmp_path):
    """The command run twice in one process (as the tests and the Python API do): --quiet on the first
    does not silence the second's notes."""
    inputs = tmp_path / "big.csv"
    inputs.write_text("t,thrust_left,thrust_right\n0,500,500\n")  # over the thrusters' bound: a note each
    args = ("simulate", "--vessel", "blueboat", "--inputs", inputs, "--duration", "2", "--out", tmp_path / "a.csv")
    quiet, loud = twin(*args, "--quiet"), twin(*args, "--force")
    assert quiet.returncode == loud.returncode == 0
    assert quiet.stderr == "" and loud.stderr.count("note: ") == 3 and "above the vessel file's bound" in loud.stderr


def test_vessel_and_model_together_are_refused(tmp_path):
    model = tmp_path / "m.json"
    shutil.copy(ROOT / "twin" / "model" / "blueboat.json", model)
    done = twin("params", "--vessel", "yellowfish", "--model", model)
    assert done.returncode == 2 and done.stderr.startswith("error: ") and "not both" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_a_copied_vessel_file_loads_with_its_mjcf_and_meshes(tmp_path):
    shutil.copy(ROOT / "twin" / "model" / "blueboat.json", tmp_path / "copy.json")
    done = twin("params", "--model", tmp_path / "copy.json")
    assert done.returncode == 0 and "m = 15.000 kg" in done.stdout, done.stderr
    shutil.copy(ROOT / "twin" / "model" / "blueboat.xml", tmp_path / "blueboat.xml")  # its meshes are not beside it
    done = twin("params", "--model", tmp_path / "copy.json")
    assert done.returncode == 0 and "m = 15.000 kg" in done.stdout, done.stderr
    data = json.loads((tmp_path / "copy.json").read_text())
    data["mjcf"] = "nowhere.xml"
    (tmp_path / "bad.json").write_text(json.dumps(data))
    done = twin("params", "--model", tmp_path / "bad.json")
    assert done.returncode == 2 and "package:" in done.stderr


def test_a_sample_step_longer_than_the_run_is_refused(tmp_path):
    done = twin("simulate", "--vessel", "blueboat", "--duration", "5", "--sample-dt", "10", "--out", tmp_path / "a.csv")
    assert done.returncode == 2 and "longer than the run" in done.stderr
    assert not (tmp_path / "a.csv").exists()


@pytest.mark.parametrize("empty", [True, False])
def test_fleet_names_an_empty_folder(tmp_path, empty):
    folder = tmp_path / "logs"
    folder.mkdir()
    if not empty:
        (folder / "notes.txt").write_text("not a recording")
    done = twin("fleet", folder, "--vessel", "blueboat", "--out", tmp_path / "out")
    assert done.returncode == 2 and "folder with no recordings" in done.stderr


def test_fleet_refuses_a_file_that_is_no_recording_before_any_log_is_diagnosed(tmp_path):
    (tmp_path / "pic.png").write_bytes(b"\x89PNG")
    (tmp_path / "a.csv").write_text("t,x,y,psi\n0,0,0,0\n")
    done = twin("fleet", tmp_path / "a.csv", tmp_path / "pic.png", "--vessel", "blueboat", "--out", tmp_path / "out")
    assert done.returncode == 2 and "pic.png': not a recognised recording (expected .tlog, DataFlash .bin, .csv or .mcap)" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and not (tmp_path / "out").exists()


def test_version_mass_cases_and_the_sitl_address_are_said_in_the_help():
    """`twin --version` prints the installed version; every --case lists its cases; `twin sitl` listens
    on this machine only unless told otherwise."""
    from importlib.metadata import version

    from twin.cli.reference import _commands

    done = twin("--version")
    assert done.returncode == 0 and done.stdout == f"twin {version('asv-twin')}\n"
    _, _, commands = _commands()
    cases = {name: p.help for name, cmd in commands for p in cmd.params if p.name == "case"}
    assert len(cases) >= 7 and all(h.startswith("mass case: min | nominal | max") for h in cases.values()), cases
    host = next(p for name, cmd in commands if name == "sitl" for p in cmd.params if p.name == "host")
    assert host.default == "127.0.0.1"


def test_a_fleet_counts_as_earlier_reports_neither_truths_nor_vessel_files(tmp_path):
    """A folder of `twin dataset` logs holds their truths: they are data beside the logs, not reports
    of logs outside the fleet; nor is a user's JSON that no fleet wrote."""
    import json

    from twin.cli.scale import other_reports

    (tmp_path / "day.truth.json").write_text(json.dumps({"vessel": "yellowfish", "effects": [], "segments": []}))
    (tmp_path / "boat.json").write_text(json.dumps({"mjcf": "package:blueboat.xml", "thrusters": {}}))
    report = {"index": 0, "log": "old_log.csv", "vessel": "yellowfish", "ok": True, "report": {}, "seconds": 1.0}
    (tmp_path / "old_log.json").write_text(json.dumps(report))
    (tmp_path / "log0.json").write_text(json.dumps({**report, "log": "log0.csv"}))
    (tmp_path / "notes.json").write_text(json.dumps({"ok": True, "operator": "anna"}))  # a user's, not a report
    assert other_reports(tmp_path, {"log0.json", "fleet.json"}) == ["old_log.json"]


def test_a_table_piped_to_a_file_is_printed_whole(capsys, monkeypatch):
    from rich.table import Table

    from twin.cli.app import console, print_table

    table = Table(title="wide")
    for k in range(10):
        table.add_column(f"β_νν [N·m·s²/rad²] {k}", justify="right")
    table.add_row(*["+1.4e-03"] * 10)
    monkeypatch.setattr("sys.stdout.isatty", lambda: False)
    page = console.width
    print_table(table)
    out = capsys.readouterr().out
    assert out.count("+1.4e-03") == 10 and "…" not in out and console.width == page


def test_a_run_made_in_a_current_and_a_wind_keeps_them_in_its_mcap_and_says_what_a_csv_loses(tmp_path):
    import twin

    done = twin_command.twin("simulate", "--vessel", "blueboat", "--scenario", "turn", "--duration", "5",
                             "--current", "0.2,90", "--wind", "5,45", "--out", tmp_path / "cw.mcap",
                             "--out", tmp_path / "cw.csv")
    assert done.returncode == 0 and "cw.csv does not hold the run's current and wind" in done.stderr, done.stderr
    meta = twin.read_recording(tmp_path / "cw.mcap").meta
    assert (meta["current_speed_m_s"], meta["current_towards_deg"], meta["wind_speed_m_s"], meta["wind_from_deg"]) \
        == (0.2, 90.0, 5.0, 45.0)
    # its replay runs in them: the twin ends near where the run did (0.21 m off: its start read from the
    # track), where in still water it ends 1.9 m away
    from twin.replay import view_runs

    def miss_m(name):
        runs = view_runs([twin.read_recording(tmp_path / name)], twin.load_vessel("blueboat"), sim=True)
        return float(np.hypot(*(runs["twin"].eta[-1, :2] - runs["recorded"].eta[-1, :2])))

    assert miss_m("cw.mcap") < 0.4 and miss_m("cw.csv") > 1.5
