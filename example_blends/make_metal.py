"""Build example_blends/cornell_metal.blend: the area-lit Cornell box whose tall block is rough metal.

The glossy test of Virtual Blue Noise Lighting (Li et al. 2022): the tall block of ``cornell_area`` becomes a
Principled BSDF with Metallic 1 and Roughness 0.3 (GGX, alpha = 0.09), a neutral silver Base Color, so its pixels
hold Cycles' ``Glossy Direct`` / ``Glossy Indirect`` / ``Glossy Color`` and the walls receive light it reflects.
Run from the repository root (it reuses make_examples.py's Cornell box):

    .venv-blender/4.2/bin/python example_blends/make_metal.py [--out DIR] [--force]
"""
import bpy

from make_examples import add_area_light, add_short_box, cornell_base
from scene_building import main, make_material

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


SCENES = {"cornell_metal": build_cornell_metal}


if __name__ == "__main__":
    main(SCENES, __doc__)
