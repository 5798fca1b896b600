"""What a new user meets: a run, a dataset or a fit never replaces a file that exists unless asked
(--force), a fleet with a log it cannot diagnose ends in exit code 2 after writing the others, a
log whose every input sample was dropped says so, a dataset too large for the machine is refused
before any work, and a coefficient whose windows disagree is not said to be held by its belief."""
from dataclasses import dataclass

import numpy as np
import pytest
from twin_command import twin

from twin.cli import ident as cli_ident
from twin.errors import TwinError
from twin.fit import simfit
from twin.effects.coefficients import Belief
from twin.prepare.timing import GyroLag


def test_simulate_refuses_to_replace_an_existing_file_without_force(tmp_path):
    log = tmp_path / "my_log.csv"
    log.write_text("t,lat,lon\n0,59,10\n")
    done = twin("simulate", "--vessel", "blueboat", "--duration", "2", "--out", log)
    assert done.returncode == 2
    assert done.stderr.strip() == f"error: --out '{log}' exists: it is kept (--force replaces it)"
    assert log.read_text() == "t,lat,lon\n0,59,10\n"
    forced = twin("simulate", "--vessel", "blueboat", "--duration", "2", "--out", log, "--force")
    assert forced.returncode == 0 and log.read_text().startswith("t,x,y,psi")


def test_dataset_refuses_to_replace_its_log_or_its_truth_without_force(tmp_path):
    truth = tmp_path / "d.truth.json"
    truth.write_text("{}")
    done = twin("dataset", "--vessel", "blueboat", "--segments", "1", "--out", tmp_path / "d.csv")
    assert done.returncode == 2 and f"'{truth}' exists" in done.stderr and truth.read_text() == "{}"
    assert not (tmp_path / "d.csv").exists()  # refused before any work


def test_a_dataset_larger_than_the_machine_is_refused_before_any_work(monkeypatch):
    monkeypatch.setattr(cli_ident, "memory_bytes", lambda: 8 * 2 ** 30)
    with pytest.raises(TwinError, match=r"--segments 100000: about 93.1 GiB .* \(8 GiB\)"):
        cli_ident.segments_fit(100_000)
    cli_ident.segments_fit(8)  # the default fits
    with pytest.raises(TwinError, match="--segments must be at least 1, got 0"):
        cli_ident.segments_fit(0)


def test_a_log_whose_every_input_sample_was_dropped_says_so(tmp_path):
    path = tmp_path / "bigpwm.csv"
    rows = ["t,north_m,east_m,heading_deg,pwm_left,pwm_right"] + [f"{k / 10:.1f},0,0,0,15000,15000" for k in range(30)]
    path.write_text("\n".join(rows) + "\n")
    done = twin("evaluate", "--vessel", "blueboat", path)
    assert done.returncode == 2
    assert "every input sample was dropped: pwm: PWM outside 500-2500 µs: 30" in done.stderr
    assert "columns pwm_left,pwm_right" not in done.stderr  # they are there


def test_a_fleet_with_a_log_it_cannot_diagnose_exits_2_after_writing_the_reports(tmp_path):
    logs = tmp_path / "logs"
    logs.mkdir()
    (logs / "empty.csv").write_text("")
    made = twin("simulate", "--vessel", "blueboat", "--scenario", "random", "--duration", "150", "--out",
                logs / "good.csv")
    assert made.returncode == 0, made.stderr
    out = tmp_path / "reports"
    done = twin("fleet", logs, "--vessel", "blueboat", "--effects", "thrust_gain", "--out", out)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1] == (f"error: 1 of 2 logs could not be diagnosed (their failure records "
                                                    f"are in {out}, the other reports are written)")
    assert (out / "fleet.json").is_file() and (out / "good.json").is_file()


def test_a_heading_ahead_of_its_gyro_is_said_to_be_early():
    assert "heading against the gyro: 0.22 s early ± 0.10 s" in GyroLag(-0.22, 0.95, 60.0, sigma_s=0.10).text()
    assert "heading against the gyro: +0.30 s late ± 0.05 s" in GyroLag(0.30, 0.95, 60.0, sigma_s=0.05).text()


@dataclass
class _Objective:
    """What _map_estimates reads of an objective: the coordinates' scales and bounds, and the σ each
    belief alone leaves at its weight."""

    held: np.ndarray

    scale = np.ones(3)

    def bounds(self):
        return np.full(3, -1e3), np.full(3, 1e3)

    def belief_sigma(self):
        return self.held


def test_a_coefficient_is_pinned_held_or_disputed_by_its_sigma_against_its_belief_alone():
    """σ belief 1, its weight leaving 0.1: a posterior σ of 0.05 is the recordings' (pinned), 0.1 the
    belief's (held), 0.6 the windows' scatter about the fit, which no belief narrows (disputed)."""
    belief = Belief(False, 1.0, "test")
    coords = [simfit.Coordinate(n, None, belief, False, 0.0, "-", 0.0) for n in ("a", "b", "c")]
    cov = np.diag([0.05, 0.1, 0.6]) ** 2
    est = simfit._map_estimates(_Objective(np.full(3, 0.1)), coords, np.zeros(3), cov, np.ones(3, bool))
    assert [(e.held_by_belief, e.disputed) for e in est] == [(False, False), (True, False), (False, True)]
    assert est[0].note.startswith("pinned by the recordings")
    assert "the recordings add little" in est[1].note
    assert "pull it different ways" in est[2].note and "6.0 times what the belief alone leaves" in est[2].note
    assert "add little" not in est[2].note
