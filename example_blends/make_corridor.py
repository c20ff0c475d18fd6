"""Build example_blends/corridor.blend: a room lit only through a corridor from a light in another room.

The "U office" of Segovia et al. (Bidirectional Instant Radiosity, sec. 5.1) at our scale: room A (seen by the
camera) and room B (holding a ceiling area light) stand side by side, 2 m apart; a 2 m door in each room's north
wall opens onto a corridor that runs along both rooms. Light needs at least two bounces to reach room A, so light
paths from the lamp rarely leave VPLs where the camera looks, while camera paths find them.

The floor plan is a grid of 1 m cells; walls, floor and ceiling are the faces between open and closed cells, all
facing into the open space. Run from the repository root:

    .venv-blender/4.2/bin/python example_blends/make_corridor.py [--out DIR] [--force]
"""
import bpy
from mathutils import Vector

from scene_building import add_light, link_object, main, make_material, make_world, mesh_object, reset_scene

HEIGHT = 2.5
ROOM_A = [(x, y) for x in range(0, 3) for y in range(0, 3)]
ROOM_B = [(x, y) for x in range(5, 8) for y in range(0, 3)]
DOORS = [(1, 3), (2, 3), (5, 3), (6, 3)]
CORRIDOR = [(x, y) for x in range(0, 8) for y in range(4, 6)]
OPEN = set(ROOM_A + ROOM_B + DOORS + CORRIDOR)
WALL_COLOR = (0.8, 0.8, 0.8)
FLOOR_COLOR = (0.6, 0.55, 0.5)
ACCENT_COLOR = (0.2, 0.35, 0.65)  # room A's west wall, so colour bleeding is visible
LAMP_POWER = 1000.0
LAMP_LOCATION = (6.5, 1.5, HEIGHT - 0.01)
CAMERA_LOCATION = (0.25, 0.25, 1.6)
CAMERA_TARGET = (2.0, 3.0, 1.0)
RESOLUTION = 128


def cell_faces():
    """Quads (4 corner tuples, counter-clockwise seen from inside) and a material key for every boundary face."""
    quads = []
    for (x, y) in sorted(OPEN):
        quads.append(([(x, y, 0), (x + 1, y, 0), (x + 1, y + 1, 0), (x, y + 1, 0)], "floor"))
        quads.append(([(x, y, HEIGHT), (x, y + 1, HEIGHT), (x + 1, y + 1, HEIGHT), (x + 1, y, HEIGHT)], "wall"))
        for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            if (x + dx, y + dy) in OPEN:
                continue
            # the shared edge, ordered so the quad faces back into cell (x, y)
            if dx == 1:
                a, b = (x + 1, y), (x + 1, y + 1)
            elif dx == -1:
                a, b = (x, y + 1), (x, y)
            elif dy == 1:
                a, b = (x + 1, y + 1), (x, y + 1)
            else:
                a, b = (x, y), (x + 1, y)
            key = "accent" if dx == -1 and (x, y) in ROOM_A else "wall"
            quads.append(([(*a, 0), (*b, 0), (*b, HEIGHT), (*a, HEIGHT)], key))
    return quads


def build_corridor():
    scene = reset_scene()
    scene.render.resolution_x = scene.render.resolution_y = RESOLUTION
    make_world(scene, (0.0, 0.0, 0.0), 0.0)
    materials = {"wall": make_material("Wall", WALL_COLOR), "floor": make_material("Floor", FLOOR_COLOR),
                 "accent": make_material("Accent", ACCENT_COLOR)}
    for key, material in materials.items():
        verts, faces = [], []
        for corners, k in cell_faces():
            if k == key:
                faces.append(tuple(range(len(verts), len(verts) + 4)))
                verts.extend(corners)
        mesh_object(key.capitalize() + "s", verts, faces, material)
    add_light("AREA", LAMP_POWER, LAMP_LOCATION, size=1.0)
    cam = bpy.data.cameras.new("Camera")
    cam.lens = 20.0
    cam.sensor_width = 36.0
    cam.clip_start = 0.05
    direction = Vector(CAMERA_TARGET) - Vector(CAMERA_LOCATION)
    obj = link_object("Camera", cam, CAMERA_LOCATION, direction.to_track_quat("-Z", "Y").to_euler())
    scene.camera = obj
    return scene


SCENES = {"corridor": build_corridor}


if __name__ == "__main__":
    main(SCENES, __doc__)
