"""How the engine notices a twin that blows up, and why MuJoCo stays quiet about it.

MuJoCo checks qpos, qvel and qacc at every step; a value that is not finite or
beyond mjMAXVAL makes it count a warning in `data.warning`, print it, append it to
MUJOCO_LOG.TXT in the working directory and reset the state to the model's
initial pose at rest, so the run goes on with plausible-looking numbers. The
twin reads those counters instead and raises (one run) or reports (a batch) the
time it diverged, so MuJoCo's own console and file log are switched off while
the twin steps: they would add lines to a one-line error and litter the user's
folder. Other warnings (contacts, constraints) cannot occur on these models,
which have neither.
"""
from __future__ import annotations

import contextlib

import mujoco

# the checks of mj_checkPos / mj_checkVel / mj_checkAcc, and what each one found bad
CHECKS = {
    mujoco.mjtWarning.mjWARN_BADQPOS: "position",
    mujoco.mjtWarning.mjWARN_BADQVEL: "velocity",
    mujoco.mjtWarning.mjWARN_BADQACC: "acceleration",
}


def flagged(data: mujoco.MjData) -> bool:
    """True once MuJoCo has found this data's state diverged (and reset it). The reset
    clears the counters before counting the warning, so a count stays at 1 however often
    it fires: only "since the counters were last cleared" can be asked."""
    return any(data.warning[kind].number for kind in CHECKS)


def clear(data: mujoco.MjData) -> None:
    for kind in CHECKS:
        data.warning[kind].number = 0


def what_diverged(data: mujoco.MjData) -> str:
    """The quantities whose check has fired (since the counters were cleared)."""
    return " and ".join(name for kind, name in CHECKS.items() if data.warning[kind].number) or "state"


@contextlib.contextmanager
def quiet_log():
    """MuJoCo's console and MUJOCO_LOG.TXT warnings off while the twin steps (module docstring);
    the previous configuration back afterwards."""
    saved = mujoco.MjLogConfig.get()
    quiet = mujoco.MjLogConfig.get()
    quiet.logto_console = False
    quiet.logto_file = False
    quiet.set()
    try:
        yield
    finally:
        saved.set()
