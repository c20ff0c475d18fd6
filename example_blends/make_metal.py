"""Build example_blends/cornell_metal.blend: the area-lit Cornell box whose tall block is rough metal.

The glossy test of Virtual Blue Noise Lighting (Li et al. 2022): the tall block of ``cornell_area`` becomes a
Principled BSDF with Metallic 1 and Roughness 0.3 (GGX, alpha = 0.09), a neutral silver Base Color, so its pixels
hold Cycles' ``Glossy Direct`` / ``Glossy Indirect`` / ``Glossy Color`` and the walls receive light it reflects.
Run from the repository root (it reuses make_examples.py's helpers):

    .venv/bin/python example_blends/make_metal.py [--out DIR] [--force]
"""
import argparse
import hashlib
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_examples import (add_area_light, add_short_box, cornell_base, make_material, save,  # noqa: E402
                           stored_fingerprint)

NAME = "cornell_metal"
METAL_COLOR = (0.9, 0.86, 0.8)
METAL_ROUGHNESS = 0.3


def build_cornell_metal():
    mats = cornell_base()
    add_short_box(mats)
    add_area_light("SQUARE")
    metal = make_material("RoughMetal", METAL_COLOR)
    bsdf = metal.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = METAL_ROUGHNESS
    bpy.data.objects["TallBox"].data.materials[0] = metal


def fingerprint():
    """This script, the helpers it imports and Blender's version: what the file depends on."""
    digest = hashlib.sha256()
    here = os.path.dirname(os.path.abspath(__file__))
    for name in ("make_metal.py", "make_examples.py"):
        with open(os.path.join(here, name), "rb") as f:
            digest.update(f.read())
    digest.update(bpy.app.version_string.encode())
    return digest.hexdigest()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.dirname(os.path.abspath(__file__)))
    parser.add_argument("--force", action="store_true", help="rewrite the file even if it is up to date")
    args = parser.parse_args(argv)
    path = os.path.join(os.path.abspath(args.out), NAME + ".blend")
    stamp = fingerprint()
    if not args.force and stored_fingerprint(path) == stamp:
        print(f"up to date: {path}")
        return
    build_cornell_metal()
    save(path, stamp)
    print(f"wrote {path} ({os.path.getsize(path)} bytes)")


if __name__ == "__main__":
    main(sys.argv[1:])
