"""Whether a change leaves the images as they were, to the bit: every example scene rendered with every method
through the command line (``python -m vpl_addon render``), one denoised F12-like render per scene, and a short bake
of each sequence scene per method, each pass's pixels hashed.

    python bench/same_images.py --write before.json         # on the old code
    python bench/same_images.py --check before.json         # on the new code: lists every pass that changed

The command line is the entry kept stable across refactors, so the same script judges code before and after a move.
Renders are small (25 % resolution, 4 samples): a bit that moves shows at any size.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from vpl_addon.core.exr import read_passes  # noqa: E402

METHODS = ("vbnl", "bidir", "ir", "smc")
SEQUENCES = ("seq_moving_object", "seq_moving_light")
SMALL = ("--percentage", "25", "--samples", "4")


def _cli(*args) -> None:
    proc = subprocess.run([sys.executable, "-m", "vpl_addon", *args], cwd=ROOT, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    if proc.returncode:
        raise SystemExit(f"python -m vpl_addon {' '.join(args)} failed:\n{proc.stderr}")


def _digests(path: pathlib.Path) -> dict[str, str]:
    passes, _ = read_passes(str(path))
    return {name: hashlib.sha256(image.tobytes()).hexdigest() for name, image in sorted(passes.items())}


def runs(scenes: list[pathlib.Path]):
    """(label, CLI arguments, output kind) of every render."""
    for blend in scenes:
        if blend.stem in SEQUENCES:
            for method in METHODS:
                yield f"{blend.stem}/bake/{method}", ("bake", str(blend), "--frames", "1:3", "--method", method,
                                                      *SMALL), "folder"
            continue
        for method in METHODS:
            yield f"{blend.stem}/{method}", ("render", str(blend), "--method", method, *SMALL), "file"
        yield f"{blend.stem}/vbnl+denoise", ("render", str(blend), "--method", "vbnl", "--denoise", *SMALL), "file"


def measure(scenes: list[pathlib.Path]) -> dict[str, dict[str, str]]:
    found = {}
    with tempfile.TemporaryDirectory() as tmp:
        for number, (label, args, kind) in enumerate(runs(scenes)):
            out = pathlib.Path(tmp, str(number) + (".exr" if kind == "file" else ""))
            _cli(*args, "-o", str(out))
            frames = sorted(out.glob("frame_*.exr")) if kind == "folder" else [out]
            for frame in frames:
                key = label if kind == "file" else f"{label}/{frame.stem}"
                found[key] = _digests(frame)
            print(label, flush=True)
    return found


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--write", help="JSON file to write the digests to")
    what.add_argument("--check", help="JSON file of earlier digests to compare with")
    parser.add_argument("scenes", nargs="*", help="the .blend files (default: example_blends/*.blend)")
    args = parser.parse_args()
    scenes = [pathlib.Path(s) for s in args.scenes] or sorted((ROOT / "example_blends").glob("*.blend"))
    found = measure(scenes)
    if args.write:
        pathlib.Path(args.write).write_text(json.dumps(found, indent=1))
        return 0
    before = json.loads(pathlib.Path(args.check).read_text())
    changed = [f"{label}: {name}" for label, passes in before.items() for name, digest in passes.items()
               if found.get(label, {}).get(name) != digest]
    print("\n".join(changed) or f"the same to the bit: {sum(map(len, before.values()))} passes of {len(before)} renders")
    return 1 if changed else 0


if __name__ == "__main__":
    sys.exit(main())
