"""The documentation: the pages made from the code and from the benchmarks' results are what they give now, the site builds in MkDocs' strict
mode (a broken link or a page left out of the navigation fails it), every picture and file the pages show exists,
README.md stays short, and its quick start runs as written."""
import json
import os
import pathlib
import re
import shlex
import shutil
import subprocess
import sys

import pytest

from conftest import ROOT

QUICK_START = "<!-- quick start"
LINK = re.compile(r"!?\[[^\]]*\]\(([^)#\s]+)(?:#[^)]*)?\)")


def _run(args, cwd=ROOT, timeout=300):
    return subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})


def test_the_generated_pages_are_what_the_code_gives():
    proc = _run([sys.executable, "docs/generate.py", "--check"])
    assert proc.returncode == 0, proc.stderr


def test_the_benchmarks_page_is_what_the_results_give():
    proc = _run([sys.executable, "bench/report.py", "--check"])
    assert proc.returncode == 0, proc.stderr


def test_the_cli_reference_holds_every_commands_help():
    page = (ROOT / "docs" / "reference" / "cli.md").read_text()
    proc = _run([sys.executable, "-m", "vpl_addon", "lightmap", "--help"], timeout=120)
    assert proc.returncode == 0, proc.stderr
    for flag in ("--texel-density", "--uv-map", "--no-denoise"):
        assert flag in proc.stdout and flag in page


def test_the_site_builds_in_strict_mode(tmp_path):
    proc = _run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")])
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "site" / "reference" / "cli" / "index.html").is_file()
    assert (tmp_path / "site" / "images" / "living_room.png").is_file()


@pytest.mark.parametrize("page", ["README.md", "CHANGELOG.md", "bench/README.md",
                                  *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").rglob("*.md"))])
def test_every_file_a_page_links_or_shows_exists(page):
    path = ROOT / page
    for target in LINK.findall(path.read_text()):
        if "://" in target:
            continue
        assert (path.parent / target).exists(), f"{page} links to {target}, which does not exist"


def test_the_readme_is_short():
    assert (ROOT / "README.md").stat().st_size <= 10 * 1024


def _quick_start() -> list[str]:
    text = (ROOT / "README.md").read_text()
    block = text[text.index(QUICK_START):].split("```sh\n", 1)[1].split("```", 1)[0]
    return [line for line in block.splitlines() if line.strip()]


def test_the_readme_quick_start_runs_as_written(tmp_path):
    """Each line of the quick start in a copy of the examples (its outputs go to out/ there, its UV-mapped scene
    beside the examples), the checkout's interpreter in place of .venv/bin/python."""
    shutil.copytree(ROOT / "example_blends", tmp_path / "example_blends")
    (tmp_path / "tests" / "references").mkdir(parents=True)
    shutil.copy(ROOT / "tests" / "references" / "cornell_area_25pct.exr", tmp_path / "tests" / "references")
    lines = _quick_start()
    assert len(lines) == 5
    outputs = []
    for line in lines:
        words = shlex.split(line)
        assert words[0] == ".venv/bin/python", line
        proc = _run([sys.executable, *words[1:]], cwd=tmp_path, timeout=600)
        assert proc.returncode == 0, f"{line}\n{proc.stderr}"
        outputs.append(proc.stdout)
    assert (tmp_path / "out" / "cornell.exr").is_file()
    frames = sorted(name for name in os.listdir(tmp_path / "out" / "sequence") if name.startswith("frame_"))
    assert frames == [f"frame_{f:04d}.exr" for f in (1, 2, 3)]
    assert (tmp_path / "out" / "lightmaps" / "Floor.exr").is_file()
    assert json.loads(outputs[-1])["Combined"]["rmae"] < 0.1  # our default render against Cycles' converged one


def test_make_docs_regenerates_nothing_and_builds_the_site():
    """The README's ``make docs``: the generated pages come out as committed, and the site is built (``site/``)."""
    pages = [ROOT / "docs" / name for name in ("reference/cli.md", "reference/methods.md", "benchmarks.md",
                                                 "gallery.md")]
    before = [page.read_bytes() for page in pages]
    proc = _run(["make", "-s", "--no-print-directory", "docs"], timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert [page.read_bytes() for page in pages] == before
    assert (ROOT / "site" / "index.html").is_file()
