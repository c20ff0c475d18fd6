"""The documentation's pages made from the code, so that they cannot drift from it: the command line's reference
from its argparse parser (``operators/cli/commands.parser``: every command's ``--help``, word for word) and the
methods' page from the method registry (``vpl_addon/methods``: each method's label, paper and flags, and every
setting users see with its label, default, command-line flag and tooltip), as Mitsuba 3 generates its plugin docs
from the code.

    .venv/bin/python docs/generate.py          # rewrite docs/reference/cli.md and docs/reference/methods.md
    .venv/bin/python docs/generate.py --check  # exit 1 if either differs from what the code gives
"""
from __future__ import annotations

import argparse
import os
import pathlib
import sys
import textwrap

ROOT = pathlib.Path(__file__).resolve().parent.parent
PAGES = ("reference/cli.md", "reference/methods.md")
WIDTH = 116  # argparse wraps its help to the terminal's width: fixed, so the page is the same everywhere


def cli_page() -> str:
    """Every command's help as argparse prints it."""
    os.environ["COLUMNS"] = str(WIDTH)
    from vpl_gi.operators.cli.commands import parser
    top = parser()
    commands = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    lines = ["# Command line", "",
             "<!-- made by docs/generate.py from operators/cli/commands.py: edit the parser, not this page -->", "",
             *_wrapped("Every command runs with the `bpy` module (`.venv/bin/python -m vpl_addon ...` in a "
                       "checkout). Bad input is one line on stderr and a non-zero exit status; nothing is written."),
             "",
             "```text", top.format_help().rstrip(), "```", ""]
    for name, sub in commands.choices.items():
        lines += [f"## {name}", "", "```text", sub.format_help().rstrip(), "```", ""]
    return "\n".join(lines)


def methods_page() -> str:
    """Each registered method and the settings users see, from the registry and the settings' ``option``s."""
    from vpl_gi.vpl_addon.methods import METHODS, PATH_REUSE, PLACEMENT
    lines = ["# Methods and their settings", "",
             "<!-- made by docs/generate.py from vpl_addon/methods: edit the methods, not this page -->", "",
             *_wrapped("The render panel's *Indirect* rows, the `--method` choices and the flags of `render` and "
                       "`bake` are made from these settings; a setting shows in the panel where its method is "
                       "chosen. The defaults below are the code's."), ""]
    shared = [s for s in PLACEMENT if s.path[0] not in METHODS]
    lines += ["## Shared by every method", "", *_table(shared), ""]
    for method in METHODS.values():
        flags = [label for label, on in (("view independent", method.view_independent),
                                         ("stable lights in a sequence", method.stable_lights),
                                         ("sums its lights (the summing gather)", method.sums_lights),
                                         ("reuses light paths across frames", method.reuses_light_paths)) if on]
        own = [s for s in PLACEMENT if s.path[0] == method.name]
        lines += [f"## `{method.name}`: {method.label}", "", *_wrapped(method.description + "."), ""]
        if flags:
            lines += [*_wrapped("Traits: " + "; ".join(flags) + "."), ""]
        if method.reuses_light_paths:
            lines += ["Path reuse applies: " + ", ".join(f"`{p}`" for p in PATH_REUSE) + ".", ""]
        lines += [*_table(own), ""] if own else ["No settings of its own.", ""]
    return "\n".join(lines)


def _wrapped(text: str) -> list[str]:
    return textwrap.wrap(text, WIDTH)


def _table(settings) -> list[str]:
    from vpl_gi.operators.cli.scene_flags import flag_of
    rows = ["| setting | default | flag | what it does |", "| --- | --- | --- | --- |"]
    for s in settings:
        flag = flag_of(s)
        default = ("on" if s.default else "off") if s.kind is bool else f"{s.default:g}" if s.kind is float \
            else str(s.default)
        text = s.option.description.replace("|", "\\|")
        rows.append(f"| {s.option.label} | {default} | `{flag}` | {text} |")
    return rows


def pages() -> dict[str, str]:
    sys.path.insert(0, str(ROOT))
    from vpl_addon.__main__ import extension_package
    extension_package()
    return {"reference/cli.md": cli_page(), "reference/methods.md": methods_page()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if a page differs from what the code gives")
    args = ap.parse_args()
    stale = []
    for name, text in pages().items():
        path = ROOT / "docs" / name
        if args.check:
            if not path.is_file() or path.read_text() != text:
                stale.append(name)
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    for name in stale:
        print(f"docs/{name} is not what the code gives: run .venv/bin/python docs/generate.py", file=sys.stderr)
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
