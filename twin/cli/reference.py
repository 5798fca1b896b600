"""The command reference as Markdown, from the typer app itself: docs/reference/cli.md is its output
(`python -m twin.cli.reference > docs/reference/cli.md`), and a test keeps the two the same, so the
page, read on the site or in the checkout, cannot drift from `twin COMMAND --help`."""
from __future__ import annotations

import inspect

import typer

from . import app as app_module


def _commands():
    group = typer.main.get_command(app_module.app)
    ctx = typer.Context(group, info_name="twin")
    return group, ctx, [(name, group.get_command(ctx, name)) for name in group.list_commands(ctx)]


def _default_text(param) -> str:
    """' (default: `x`)' as `--help` shows it, or '' where there is none to show: an on/off pair
    names the side that holds (a seed of 0 is a default too, though it equals False)."""
    default = param.default
    if getattr(param, "is_flag", False):
        if param.secondary_opts:
            return f" (default: `{param.opts[0] if default else param.secondary_opts[0]}`)"
        return ""
    if default is None or default is False or (isinstance(default, (tuple, list)) and not default):
        return ""
    return f" (default: `{default}`)"


def _option_row(param) -> str:
    names = ", ".join(f"`{o}`" for o in (*param.opts, *param.secondary_opts))
    if param.param_type_name == "argument":
        names = f"`{(param.metavar or param.name).upper()}`"
    shown = _default_text(param)
    text = " ".join((getattr(param, "help", None) or "").split()).replace("|", "\\|")
    return f"| {names} | {text}{shown} |"


def markdown() -> str:
    """Every command in the order `twin --help` lists them: its summary, its description and a
    table of its arguments and options."""
    group, _, commands = _commands()
    out = ["Every command of `twin`, in the order of the workflow. Every bad input ends in one "
           "`error: ...` line on stderr and exit code 2; `--quiet` (before or after the command) turns "
           "off progress bars and notes; `twin --version` prints the version.", ""]
    for name, cmd in commands:
        out += [f"## twin {name}", "", cmd.short_help or "", ""]
        doc = inspect.cleandoc(cmd.help or "")
        paragraphs = [" ".join(p.split()) for p in doc.split("\n\n")[1:]]
        out += [p for par in paragraphs for p in (par, "")]
        params = [p for p in cmd.params if p.name not in ("help",)]
        if params:
            out += ["| argument or option | meaning |", "| --- | --- |", *map(_option_row, params), ""]
    return "\n".join(out)


def page() -> str:
    """docs/reference/cli.md as it must read."""
    return "# Commands\n\n" + markdown().rstrip("\n") + "\n"


if __name__ == "__main__":
    print(page(), end="")
