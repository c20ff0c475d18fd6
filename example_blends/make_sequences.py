"""Build the 24-frame animation examples: the Cornell box of make_examples.py with a moving light, and with a
moving object.

* ``seq_moving_light.blend``: the classic box with both blocks; a 60 W point light (radius 0.05 m) travels along a
  straight line under the ceiling from the red wall's side to the green wall's side, frames 1 to 24.
* ``seq_moving_object.blend``: the classic box lit by its 40 W area light; the short block slides 0.8 m across
  the floor towards the red wall and turns by 30 degrees, frames 1 to 24.

Both are 128x128 (the references cost a Cycles render per frame) with linear keyframes and saved at frame 1. Run
from the repository root (it reuses make_examples.py's Cornell box):

    .venv-blender/4.2/bin/python example_blends/make_sequences.py [--out DIR] [--force]
"""
import math

import bpy

from make_examples import add_area_light, add_short_box, cornell_base
from scene_building import add_light, main

RESOLUTION = 128
FRAMES = (1, 24)
LIGHT_PATH = ((-0.6, -0.2, 1.6), (0.6, 0.4, 1.6))  # the point light's start and end
LIGHT_POWER = 60.0
BOX_SLIDE = (-0.8, 0.0, 0.0)  # the short block's displacement over the sequence
BOX_TURN_DEG = 30.0


def _sequence_scene():
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "LINEAR"
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = RESOLUTION
    scene.frame_start, scene.frame_end = FRAMES
    scene.frame_set(FRAMES[0])
    return scene


def build_moving_light():
    mats = cornell_base()
    add_short_box(mats)
    _sequence_scene()
    light = add_light("POINT", LIGHT_POWER, LIGHT_PATH[0], shadow_soft_size=0.05)
    for frame, location in zip(FRAMES, LIGHT_PATH):
        light.location = location
        light.keyframe_insert("location", frame=frame)
    bpy.context.scene.frame_set(FRAMES[0])


def build_moving_object():
    mats = cornell_base()
    box = add_short_box(mats)
    add_area_light("SQUARE")
    _sequence_scene()
    start, turn = tuple(box.location), box.rotation_euler.z
    for frame, fraction in zip(FRAMES, (0.0, 1.0)):
        box.location = tuple(s + fraction * d for s, d in zip(start, BOX_SLIDE))
        box.rotation_euler.z = turn + fraction * math.radians(BOX_TURN_DEG)
        box.keyframe_insert("location", frame=frame)
        box.keyframe_insert("rotation_euler", frame=frame)
    bpy.context.scene.frame_set(FRAMES[0])


SCENES = {"seq_moving_light": build_moving_light, "seq_moving_object": build_moving_object}


if __name__ == "__main__":
    main(SCENES, __doc__)
