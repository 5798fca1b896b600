"""The documentation: the site builds with --strict, the bibliography page is the code's, the README
stays short and free of development history, and every example of the README and the Guide runs.

Examples are the ```bash and ```python blocks (```text blocks are shown, not run). A page's blocks run
in order in one folder, and the Guide's pages in their order in one folder, since a tutorial builds on
the files the pages before it made. Lines that install or run the suite itself (pip, git clone, cd,
python -m pytest) are not run. A block whose first line is `# needs ../shared/...` skips when that
path is absent. The Guide's plain `twin ...` lines run in the test process (the same entry point,
without a new interpreter's imports), the README's through the shell.
"""
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

import twin_command

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
GUIDE = sorted((DOCS / "guide").glob("*.md"))
NOT_RUN = re.compile(r"^\s*(pip |git clone|cd |python -m pytest)")
BLOCK = re.compile(r"^```(bash|python)\n(.*?)^```", re.S | re.M)


def blocks(page: Path) -> list[tuple[str, str]]:
    return [(lang, body) for lang, body in BLOCK.findall(page.read_text())]


def run_block(lang: str, body: str, where: Path, page: Path, in_process: bool = True) -> None:
    """A block's lines in turn; a plain `twin ...` line in this process (tests/twin_command.py) unless
    `in_process` is False, as the README's are: they show the console script on PATH works."""
    first = body.splitlines()[0] if body.strip() else ""
    if first.startswith("# needs "):
        needed = (ROOT / first[len("# needs "):].strip()).resolve()
        if not needed.exists():
            pytest.skip(f"{page.name}: needs {needed}")
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    if lang == "python":
        done = subprocess.run([sys.executable, "-c", body], cwd=where, capture_output=True, text=True, env=env,
                              timeout=600)
        assert done.returncode == 0, f"{page.name}: python block failed:\n{body}\n{done.stderr[-2000:]}"
        return
    for line in body.splitlines():
        if not line.strip() or line.lstrip().startswith("#") or NOT_RUN.match(line):
            continue
        args = twin_command.in_process(line) if in_process else None
        if args is not None:
            done = twin_command.twin(*args, cwd=where)
        else:
            done = subprocess.run(["bash", "-c", line], cwd=where, capture_output=True, text=True, env=env,
                                  timeout=600)
        assert done.returncode == 0, f"{page.name}: `{line}` failed:\n{done.stderr[-2000:]}"


def test_the_readme_is_short_and_has_no_development_history():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 250
    for word in ("session", "fresh seed", "tried and reverted", "seed 00"):
        assert word not in text.lower(), word


def test_the_docs_speak_of_sessions_only_as_ardupilot_sitl_sessions():
    wrong = []
    for path in [ROOT / "README.md", *DOCS.rglob("*.md"), *(ROOT / "twin").rglob("*.py")]:
        for n, line in enumerate(path.read_text().splitlines(), 1):
            if re.search(r"session", line, re.I) and not re.search(r"sitl|ardupilot", path.as_posix() + line, re.I):
                wrong.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not wrong, "\n".join(wrong)


def test_the_bibliography_page_is_the_codes():
    from twin.references import markdown

    assert (DOCS / "bibliography.md").read_text() == markdown(), \
        "docs/bibliography.md is out of date: python -m twin.references > docs/bibliography.md"


def test_every_key_cited_is_in_the_bibliography():
    from twin.references import BIBLIOGRAPHY

    cited = set()
    files = [ROOT / "README.md", *DOCS.rglob("*.md"), *(ROOT / "twin").rglob("*.py"), *(ROOT / "twin" / "model").glob("*")]
    for path in files:
        cited |= set(re.findall(r"\[([A-Z][A-Za-z]+(?:-[A-Z0-9][A-Za-z0-9]*)+)[\] ;]", path.read_text(errors="ignore")))
    unknown = sorted(k for k in cited if k not in BIBLIOGRAPHY)
    assert not unknown, f"cited but not in twin/references.py: {unknown}"


def test_the_site_builds_strictly(tmp_path):
    pytest.importorskip("mkdocs", reason="the docs extra is not installed (pip install -e '.[docs]')")
    pytest.importorskip("mkdocstrings", reason="the docs extra is not installed (pip install -e '.[docs]')")
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
                          cwd=ROOT, capture_output=True, text=True, timeout=600,
                          env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    # without -q: mkdocs -q leaves its warnings uncounted, and --strict then passes whatever they say
    assert done.returncode == 0, done.stderr[-3000:]
    assert "twin identify" in (tmp_path / "site" / "reference" / "cli" / "index.html").read_text()
    # a Returns paragraph that wraps is one return value, not a row per line
    api = (tmp_path / "site" / "reference" / "api" / "index.html").read_text()
    simulate = api[api.index('id="twin.api.simulate"'):api.index('id="twin.api.simulate_run"')]
    returns = simulate[simulate.index("Returns"):simulate.index("Raises")]
    assert returns.count("<tr") == 2, returns  # its heading and one value


def test_the_readme_examples_run(tmp_path):
    for lang, body in blocks(ROOT / "README.md"):
        run_block(lang, body, tmp_path, ROOT / "README.md", in_process=False)


@pytest.fixture(scope="module")
def guide_folder(tmp_path_factory):
    return tmp_path_factory.mktemp("guide")


@pytest.mark.parametrize("page", GUIDE, ids=[p.stem for p in GUIDE])
def test_the_guide_examples_run(page, guide_folder):
    """In the Guide's order, in one folder: a page uses what the pages before it made."""
    for lang, body in blocks(page):
        run_block(lang, body, guide_folder, page)


def test_every_guide_page_has_an_example_or_says_why_not():
    for page in GUIDE:
        assert blocks(page) or "```text" in page.read_text(), page.name


def test_results_pages_name_their_data_and_run():
    pages = [p for p in (DOCS / "results").glob("*.md") if p.name != "index.md"]
    assert pages
    for page in pages:
        text = page.read_text()
        assert "Generated by" in text and "commit" in text, page.name
        assert (DOCS / "results" / "data" / f"{page.stem}.json").exists(), page.name


def test_no_proof_run_folders_in_docs():
    assert not [p for p in DOCS.rglob("*") if p.is_dir() and re.search(r"fresh_seeds|nulls_\d", p.name)]


def test_the_tour_notebook_runs_and_names_the_current_it_conceals(tmp_path, monkeypatch):
    """docs/guide/tour.ipynb, its code cells in order in one namespace (no Jupyter needed): the
    current of 0.15 m/s towards 90° it conceals is named within 10 % and 10°, and the amended twin's
    sway fits where the prior's did not; its scratch folder is gone once it has run."""
    nb = json.loads((DOCS / "guide" / "tour.ipynb").read_text())
    assert nb["nbformat"] == 4
    cells = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert all(not c["outputs"] and c["execution_count"] is None for c in cells), "commit the notebook cleared"
    monkeypatch.chdir(tmp_path)
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    space: dict = {}
    for cell in cells:
        exec(compile("".join(cell["source"]), "tour.ipynb", "exec"), space)
    assert not list(scratch.iterdir()), "the tour leaves its scratch folder behind"
    named = {e.name: e for e in space["found"].effects}
    assert list(named) == ["current"]
    values = {p.name: p.value for p in named["current"].parameters}
    assert values["speed_m_s"] == pytest.approx(0.15, rel=0.1) and values["dir_deg"] == pytest.approx(90.0, abs=10.0)
    interval = next(p.ci95 for p in named["current"].parameters if p.name == "speed_m_s")
    assert interval is not None and interval[0] - 0.01 <= 0.15 <= interval[1] + 0.01
    amended = space["found"].amended.environment
    assert amended.current_speed_m_s == pytest.approx(values["speed_m_s"], rel=1e-6)
    assert space["before"].score("v").r2 < 0.5 < 0.9 < space["after"].score("v").r2


def test_the_command_reference_page_is_the_commands_own_help():
    """docs/reference/cli.md is generated from the typer app; regenerate it with
    `python -m twin.cli.reference > docs/reference/cli.md` after changing a command's help."""
    from twin.cli.reference import page

    assert (DOCS / "reference" / "cli.md").read_text() == page(), "regenerate docs/reference/cli.md"


def test_the_command_reference_shows_the_defaults_help_shows():
    """A seed of 0 is a default (though 0 == False), an on/off pair names the side that holds, and
    an option without a default shows none."""
    from twin.cli.reference import page

    text = page()
    simulate = text.split("## twin simulate", 1)[1].split("## twin ", 1)[0]
    assert "random seed (scenario 'random', the sea's components) (default: `0`)" in simulate
    identify = text.split("## twin identify", 1)[1].split("## twin ", 1)[0]
    assert "(default: `--calibration`)" in identify
    sitl = text.split("## twin sitl", 1)[1].split("## twin ", 1)[0]
    assert "(default: `--lockstep`)" in sitl and "(default) (default" not in sitl
    assert "| `--model` | vessel description file (e.g. written by `twin identify`), instead of --vessel |" in simulate


def test_the_vessel_file_reference_names_every_field():
    """A field the loader takes but the reference does not name is one a user cannot know of."""
    from dataclasses import fields

    from twin.physics.priors import Design
    from twin.vessel import VESSEL_FILE_KEYS, AddedMass, Damping, Environment, MassCase, Sensors, ThrusterModel, WindLoad

    page = (ROOT / "docs" / "reference" / "vessel-file.md").read_text(encoding="utf-8")
    names = set(VESSEL_FILE_KEYS) | {f.name for c in (AddedMass, Damping, ThrusterModel, WindLoad, Environment,
                                                      Sensors, MassCase, Design) for f in fields(c)}
    unnamed = sorted(n for n in names if f"`{n}`" not in page)
    assert not unnamed, unnamed
