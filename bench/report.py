"""The documentation's pages made from measurements: ``docs/benchmarks.md`` from the folders of ``bench/results/``,
each named by what it measures and holding the command that measured it (``command.txt``), its figures (the bench's
``summary.txt``, CSV or JSON) and its plots, which are copied to ``docs/images/bench/``; and ``docs/gallery.md``
from the pictures ``bench/gallery.py`` wrote (``docs/images/<scene>.png`` and its ``.json``).

    .venv/bin/python bench/report.py          # rewrite both pages and the plots
    .venv/bin/python bench/report.py --check  # exit 1 if a page is not what the results give

A new measurement is a folder here and an entry of ``SECTIONS``; nothing on the page is typed by hand.
"""
from __future__ import annotations

import argparse
import csv
import json
import pathlib
import re
import shutil
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
PAGE = ROOT / "docs" / "benchmarks.md"
GALLERY = ROOT / "docs" / "gallery.md"
PICTURES = ROOT / "docs" / "images"
PLOTS = PICTURES / "bench"
FIRST = ("living_room", "cornell_area")  # the gallery's order: these, then the rest by name

# a line of the bench's summary: "  equal time 10 s: cycles+oidn rMAE 0.0151 / vbnl+oidn 0.0125 = 1.21x"
EQUAL_TIME = re.compile(r"equal time (\d+) s: \S+ (?:block |clean )?\S+ [\d.]+ / \S+ [\d.]+ = ([\d.]+)x")
HEADER = re.compile(r"^(\S+), Combined, against cycles\+oidn(, rMAE of 4 x 4 blocks)?(, relative RMSE.*)?:$")


def _command(folder: pathlib.Path) -> list[str]:
    """What ``command.txt`` says: its first line, then each command as a code block."""
    first, *commands = (folder / "command.txt").read_text().strip().splitlines()
    return [first, "", "```sh", *commands, "```", ""]


def picture_against_cycles(folder: pathlib.Path, title: str) -> list[str]:
    """Cycles + OIDN's error over ours at equal time, per scene, in rMAE, 4 x 4 blocks and clean rRMSE (where the
    scene has a twin reference), from the bench's summary; and each scene's plot."""
    ratios: dict[str, dict[str, dict[str, str]]] = {}
    metric = None
    for line in (folder / "summary.txt").read_text().splitlines():
        header = HEADER.match(line)
        if header:
            scene, metric = header.group(1), "blocks" if header.group(2) else "clean" if header.group(3) else "rMAE"
            ratios.setdefault(scene, {}).setdefault(metric, {})
        elif metric and line.startswith("  equal time"):
            found = EQUAL_TIME.search(line)
            if found:
                ratios[scene][metric][found.group(1)] = found.group(2) + "x"
        elif not line.startswith("  "):
            metric = None
    times = ("2", "10", "30")
    rows = [f"## {title}", "", *_command(folder),
            "Cycles + OIDN's error over ours at equal time (above 1: ours is closer to the converged image):", "",
            "| scene | " + " | ".join(f"{m} {t} s" for m in ("rMAE", "blocks", "clean rRMSE") for t in times) + " |",
            "| --- |" + " --- |" * 9]
    for scene, by_metric in ratios.items():
        cells = [by_metric.get(m, {}).get(t, "n/a") for m in ("rMAE", "blocks", "clean") for t in times]
        rows.append(f"| {scene} | " + " | ".join(cells) + " |")
    return rows + ["", *_shown_plots(folder)]


def _shown_plots(folder: pathlib.Path) -> list[str]:
    """The page's lines showing ``folder``'s plots, from their copies (``plots``)."""
    lines = []
    for plot in sorted(folder.glob("*.png")):
        lines += [f"![{plot.stem}]({(PLOTS / folder.name / plot.name).relative_to(PAGE.parent).as_posix()})", ""]
    return lines


def table(file: str):
    """A section that is the folder's markdown table ``file`` under its command."""
    def section(folder: pathlib.Path, title: str) -> list[str]:
        return [f"## {title}", "", *_command(folder), *(folder / file).read_text().strip().splitlines(), ""]
    return section


def lightmaps(folder: pathlib.Path, title: str) -> list[str]:
    comparison = json.loads((folder / "comparison.json").read_text())
    scaling = json.loads((folder / "scaling.json").read_text())
    rows = [f"## {title}", "", *_command(folder),
            f"{comparison['size']} x {comparison['size']} texels a mesh, against Cycles' bake at "
            f"{comparison['reference_samples']} samples; *lit* leaves out the texels whose centre lies inside a box "
            f"(Cycles bakes nothing there); *clean* is the lit texels' relative RMSE with the references' own noise "
            f"taken out.", "",
            "| bake | seconds | rMAE | lit rMAE | mean ratio | clean rRMSE |", "| --- | --- | --- | --- | --- | --- |"]
    for row in comparison["rows"]:
        clean = f"{row['clean_rrmse_lit']:.4f}" if "clean_rrmse_lit" in row else ""
        seconds = f"{row['seconds']:.2f}" if row["seconds"] else ""
        rows.append(f"| {row['what']} | {seconds} | {row['rmae']:.4f} | {row['rmae_lit']:.4f} | "
                    f"{row['mean_ratio']:.4f} | {clean} |")
    rows += ["", f"One VPL set for every object, {scaling['texels']:,} texels in all:", "",
             "| objects | size | seconds | seconds a million texels |", "| --- | --- | --- | --- |"]
    for row in scaling["scaling"]:
        rows.append(f"| {row['objects']} | {row['size']} | {row['seconds']:.2f} | {row['seconds_per_mtexel']:.1f} |")
    return rows + [""]


def scaling(folder: pathlib.Path, title: str) -> list[str]:
    """Wall time per sweep, and its exponent: the slope of log(wall) against log(count)."""
    sweeps: dict[str, list[tuple[int, float]]] = {}
    with open(folder / "scaling.csv") as f:
        for row in csv.DictReader(f):
            sweeps.setdefault(row["sweep"], []).append((int(row["count"]), float(row["wall_s"])))
    rows = [f"## {title}", "", *_command(folder), "| sweep | counts | wall seconds | exponent |",
            "| --- | --- | --- | --- |"]
    for sweep, points in sweeps.items():
        counts, walls = zip(*points)
        slope = np.polyfit(np.log(counts), np.log(walls), 1)[0]
        rows.append(f"| {sweep} | {' / '.join(f'{c:,}' for c in counts)} | {' / '.join(f'{w:.2f}' for w in walls)} "
                    f"| {slope:.2f} |")
    return rows + [""]


def glossy(folder: pathlib.Path, title: str) -> list[str]:
    rows = [f"## {title}", "", *_command(folder), "| method | budget | seconds | Glossy Indirect rMAE | its mean ratio "
            "| Combined rMAE |", "| --- | --- | --- | --- | --- | --- |"]
    with open(folder / "glossy.csv") as f:
        for row in csv.DictReader(f):
            rows.append(f"| {row['method']} | {row['budget']} | {row['seconds']} | {row['glossy_indirect_rmae']} | "
                        f"{row['glossy_indirect_ratio']} | {row['combined_rmae']} |")
    return rows + [""]


def scene_check(folder: pathlib.Path, title: str) -> list[str]:
    rows = [f"## {title}", "", *_command(folder), "| scene | Cycles samples | mean ratio (R, G, B) | reference |",
            "| --- | --- | --- | --- |"]
    for entry in json.loads((folder / "check.json").read_text()):
        ratio = " / ".join(f"{v:.3f}" for v in entry.get("ratio_rgb") or [])
        rows.append(f"| {entry['scene']} | {entry['samples']} | {ratio or 'none shipped'} | "
                    f"{entry.get('reference') or ''} |")
    return rows + ["", *_shown_plots(folder)]


# bench/profile.py's lines: the render's figures, its stages, and the stages' waits on embree
PROFILE_WALL = re.compile(r"^wall ([\d.]+) s, ([\d.]+) M rays, ([\d.]+) M rays/s; raw embreex ([\d.]+) M rays/s on "
                          r"\d+ threads: (\d+) %; peak memory (\d+) MB")
PROFILE_WAIT = re.compile(r"^waiting on embree: .*; in all [\d.]+ thread-s, (\d+) % of wall")


def profiles(folder: pathlib.Path, title: str) -> list[str]:
    """One row per scene's profile (``bench/profile.py``'s output in ``<scene>.txt``): wall time, rays per second
    beside raw embreex's, the share of the threads' time spent waiting on embree, peak memory; then each scene's
    stages as the profile prints them."""
    rows = [f"## {title}", "", *_command(folder),
            "| scene | wall s | M rays | M rays/s | raw embreex M rays/s | share of raw | threads' time in embree | "
            "peak MB |", "| --- |" + " --- |" * 7]
    stages = []
    for path in sorted(folder.glob("*.txt")):
        if path.name == "command.txt":
            continue
        lines = path.read_text().splitlines()
        wall = next(filter(None, map(PROFILE_WALL.match, lines)))
        wait = next(filter(None, map(PROFILE_WAIT.match, lines)), None)
        share = f"{wait.group(1)} %" if wait else "n/a"
        rows.append(f"| {path.stem} | {wall.group(1)} | {wall.group(2)} | {wall.group(3)} | {wall.group(4)} | "
                    f"{wall.group(5)} % | {share} | {wall.group(6)} |")
        stages += [f"- {path.stem}: " + line for line in lines if line.startswith(("stages", "waiting"))]
    return rows + ["", "Seconds by stage (the blocks' stages summed over their threads):", "", *stages, ""]


SECTIONS = (  # (folder, title, how its figures become a section)
    ("examples", "The denoised picture on the example scenes", picture_against_cycles),
    ("corridor", "The corridor to 30 s", picture_against_cycles),
    ("converted_scenes", "The denoised picture on the converted public scenes", picture_against_cycles),
    ("living_room", "The living room", picture_against_cycles),
    ("pass_table", "Every light pass against Cycles", table("pass_table.md")),
    ("flat_blocks", "Flat squares in the light passes", table("flat_blocks.md")),
    ("caustics", "The helmet's caustics on its ground", table("caustics.md")),
    ("glossy", "Glossy Indirect on rough metal", glossy),
    ("lightmap", "Lightmaps against Cycles' bake", lightmaps),
    ("scaling", "Scaling with triangles, pixels and VPLs", scaling),
    ("scene_check", "The converted scenes against the renders shipped with them", scene_check),
    ("profile", "Where a render's time goes", profiles),
)


def page() -> str:
    lines = ["# Benchmarks", "",
             "<!-- made by bench/report.py from bench/results/: edit the results, not this page -->", "",
             "Every figure below is read from a folder of `bench/results/`, named by what it measures, with the "
             "command that measured it. Runs on the project's 2-core machine; seconds move with the machine's load, "
             "so compare the ratios. How to run the benchmarks: `bench/README.md`.", ""]
    for name, title, section in SECTIONS:
        lines += section(RESULTS / name, title)
    return "\n".join(lines)


def gallery() -> str:
    """Each picture of ``bench/gallery.py`` with its scene, size, reference and figures."""
    figures = {path.stem: json.loads(path.read_text()) for path in PICTURES.glob("*.json")}
    order = [name for name in FIRST if name in figures] + sorted(set(figures) - set(FIRST))
    lines = ["# Gallery", "", "<!-- made by bench/report.py from docs/images/*.json: run bench/gallery.py -->", "",
             "Each scene rendered with the add-on's defaults (denoised), by Cycles at the samples whose time comes "
             "nearest ours, and by Cycles + OpenImageDenoise at those samples, on the project's 2-core machine; "
             "under each its wall time and the rMAE of Combined against a converged Cycles render. Made by "
             "`make gallery` (`bench/gallery.py`).", ""]
    for name in order:
        f = figures[name]
        width, height = f["size"]
        cells = "; ".join(f"{row['label']} {row['seconds']:.1f} s, rMAE {row['rmae']:.3f}" for row in f["rows"])
        lines += [f"## {name}", "", f"![{name}](images/{name}.png)", "",
                  f"{width} x {height}, against {f['reference']}: {cells}.", ""]
    return "\n".join(lines)


def plots() -> dict[pathlib.Path, pathlib.Path]:
    """Each result plot the page shows -> where the documentation keeps its copy."""
    return {plot: PLOTS / plot.parent.name / plot.name for name, _, _ in SECTIONS
            for plot in sorted((RESULTS / name).glob("*.png"))}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if the page or a plot is not what the results give")
    args = ap.parse_args()
    pages, copies = {PAGE: page(), GALLERY: gallery()}, plots()
    if args.check:
        stale = [str(path) for path, text in pages.items() if not path.is_file() or path.read_text() != text]
        stale += [str(copy) for source, copy in copies.items()
                  if not copy.is_file() or copy.read_bytes() != source.read_bytes()]
        for path in stale:
            print(f"{path} is not what the measurements give: run .venv/bin/python bench/report.py", file=sys.stderr)
        return 1 if stale else 0
    shutil.rmtree(PLOTS, ignore_errors=True)
    for source, copy in copies.items():
        copy.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source, copy)
    for path, text in pages.items():
        path.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
