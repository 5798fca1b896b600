"""The `twin` command run inside the test process: the same entry point (`twin.cli.main`, which
`twin` and `python -m twin` call) with the arguments, working folder and environment given, its
stdout, stderr and exit code returned as a subprocess's would be. A new interpreter spends about two
seconds importing the package before a command starts; in the test process that is paid once.

What a command may change in the process is put back after it: the working folder, sys.argv, the
environment, MuJoCo's passive callback and the SIGINT / SIGTERM handlers. Tests of what only a
process shows (the console script on PATH, signals, Ctrl-C) start one.
"""
from __future__ import annotations

import contextlib
import io
import os
import shlex
import signal
import subprocess
import sys
from pathlib import Path

import mujoco

SHELL = set("|&;<>()$`\\*?[]{}~")  # a line with any of these needs a shell


def twin(*args, cwd: Path | str | None = None, env: dict | None = None,
         timeout: float | None = None) -> subprocess.CompletedProcess:
    """`twin ARGS...` in this process (module docstring); `timeout` is accepted for a subprocess's
    signature and not enforced."""
    from twin.cli import main

    argv = ["twin", *map(str, args)]
    saved_argv, saved_cwd, saved_env = sys.argv, os.getcwd(), dict(os.environ)
    saved_passive = mujoco.get_mjcb_passive()
    saved_signals = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    out, err = io.StringIO(), io.StringIO()
    code = 0
    try:
        sys.argv = argv
        if env is not None:
            os.environ.clear()
            os.environ.update(env)
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main()
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        sys.argv = saved_argv
        os.chdir(saved_cwd)
        if env is not None:
            os.environ.clear()
            os.environ.update(saved_env)
        mujoco.set_mjcb_passive(saved_passive)
        for s, handler in saved_signals.items():
            signal.signal(s, handler)
    return subprocess.CompletedProcess(argv, code, out.getvalue(), err.getvalue())


def in_process(line: str) -> list[str] | None:
    """The arguments of a shell line that is a plain `twin ...` command (no pipes, redirections,
    variables or globs), else None."""
    if not line.startswith("twin ") or any(ch in SHELL for ch in line):
        return None
    words = shlex.split(line)
    return words[1:]
