"""Build the VPL GI example scenes (Cornell box variants) from scratch.

Run with Blender 4.2's Python module (the version matrix's venv, ``make examples``), the oldest Blender supported,
so that every supported one opens the files:

    .venv-blender/4.2/bin/python example_blends/make_examples.py [--out DIR] [--force]

Each scene starts from ``scene_building.reset_scene`` (metres, Z up, 256x256, Cycles with 64 samples and 8 bounces)
and is written by ``scene_building.main`` as ``<name>.blend``. ``make_metal.py``, ``make_pbr.py`` and
``make_sequences.py`` build their scenes on this file's Cornell box.

Scene conventions: a World whose Background node sets colour and strength, and a perspective camera at
(0, -3.9, 1) looking along +Y into the open front of a 2 m Cornell box spanning x, y in [-1, 1], z in [0, 2].
All materials are pure diffuse Principled BSDFs (Roughness 1, Metallic 0, Specular IOR Level 0).
"""

import math

import bpy  # must come first: it makes bmesh/mathutils importable
import bmesh
from mathutils import Vector

from scene_building import (add_light, box_geometry, link_object, main, make_material, make_world, mesh_object,
                            planar_grid, reset_scene)

# Classic Cornell box reflectances (linear RGB).
WHITE = (0.725, 0.71, 0.68)
RED = (0.63, 0.065, 0.05)
GREEN = (0.14, 0.45, 0.091)

# Checker texture: 64x64 pixels, cells of 8x8 pixels, two colours.
CHECKER_SIZE = 64
CHECKER_CELL = 8
CHECKER_COLORS = ((0.8, 0.8, 0.8), (0.2, 0.3, 0.6))

EMITTER_COLOR = (1.0, 0.6, 0.2)
EMITTER_STRENGTH = 5.0

CAMERA_LOCATION = (0.0, -3.9, 1.0)
CAMERA_VFOV_DEG = 39.0
SENSOR_WIDTH_MM = 36.0

X = Vector((1.0, 0.0, 0.0))
Y = Vector((0.0, 1.0, 0.0))
Z = Vector((0.0, 0.0, 1.0))


# --------------------------------------------------------------------------
# Materials
# --------------------------------------------------------------------------

def make_checker_image(name="Checker"):
    """64x64 two-colour checkerboard, generated and packed into the .blend."""
    size, cell = CHECKER_SIZE, CHECKER_CELL
    image = bpy.data.images.new(name, width=size, height=size, alpha=False)
    pixels = []
    for row in range(size):
        for col in range(size):
            color = CHECKER_COLORS[((row // cell) + (col // cell)) % 2]
            pixels.extend((*color, 1.0))
    image.pixels.foreach_set(pixels)
    image.update()
    image.pack()
    return image


def make_checker_material(image):
    """Diffuse material whose Base Color is the checker image on 'UVMap'."""
    mat = make_material("Checker", CHECKER_COLORS[0])
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    uv_node = nodes.new("ShaderNodeUVMap")
    uv_node.uv_map = "UVMap"
    uv_node.location = (-700.0, 300.0)
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.location = (-450.0, 300.0)
    links.new(uv_node.outputs["UV"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def make_base_materials():
    """The three classic Cornell box materials, keyed by name."""
    return {
        "White": make_material("White", WHITE),
        "Red": make_material("Red", RED),
        "Green": make_material("Green", GREEN),
    }


# --------------------------------------------------------------------------
# Room, blocks, extra geometry
# --------------------------------------------------------------------------

# Window hole in the left wall and the sun shining through it.  The window
# sits low and towards the open front, and the sun is turned a little towards
# the back wall, so that the sunlit patch lands on the floor in front of the
# tall block and on the block's front face, both in view of the camera
# (higher windows put the patch behind the short block).
WINDOW_Y = (-0.7, -0.1)
WINDOW_Z = (0.4, 1.0)
SUN_ELEVATION_DEG = 35.0
SUN_AZIMUTH_DEG = 25.0


def build_room(mats, floor_material=None, window=False):
    """Cornell box walls as separate objects, normals facing into the room.

    The front side (y = -1) is open.  With ``window`` the left wall gets a
    rectangular hole (WINDOW_Y x WINDOW_Z) built from eight planar quads.
    The floor carries a UV map spanning 0..1 over its extent.
    """
    floor_material = floor_material or mats["White"]
    # Floor: normal +Z (X x Y).
    verts, faces, uvs = planar_grid((-1, -1, 0), 2 * X, 2 * Y)
    mesh_object("Floor", verts, faces, floor_material, uvs=uvs)
    # Ceiling: normal -Z (Y x X).
    verts, faces, _ = planar_grid((-1, -1, 2), 2 * Y, 2 * X)
    mesh_object("Ceiling", verts, faces, mats["White"])
    # Back wall at y = 1: normal -Y (X x Z).
    verts, faces, _ = planar_grid((-1, 1, 0), 2 * X, 2 * Z)
    mesh_object("BackWall", verts, faces, mats["White"])
    # Left wall at x = -1: normal +X (Y x Z), optionally with a window.
    if window:
        u_breaks = (0.0, (WINDOW_Y[0] + 1) / 2, (WINDOW_Y[1] + 1) / 2, 1.0)
        v_breaks = (0.0, WINDOW_Z[0] / 2, WINDOW_Z[1] / 2, 1.0)
        verts, faces, _ = planar_grid((-1, -1, 0), 2 * Y, 2 * Z,
                                      u_breaks, v_breaks, holes={(1, 1)})
    else:
        verts, faces, _ = planar_grid((-1, -1, 0), 2 * Y, 2 * Z)
    mesh_object("LeftWall", verts, faces, mats["Red"])
    # Right wall at x = 1: normal -X (Z x Y).
    verts, faces, _ = planar_grid((1, -1, 0), 2 * Z, 2 * Y)
    mesh_object("RightWall", verts, faces, mats["Green"])


def add_box(name, size, location, angle_deg, material):
    """Box object standing on the floor, turned ``angle_deg`` about Z."""
    verts, faces = box_geometry(*size)
    return mesh_object(name, verts, faces, material, location=location,
                       rotation=(0.0, 0.0, math.radians(angle_deg)))


def add_short_box(mats):
    return add_box("ShortBox", (0.6, 0.6, 0.6), (0.35, -0.3, 0.0), -17.0,
                   mats["White"])


def add_tall_box(mats):
    return add_box("TallBox", (0.6, 0.6, 1.2), (-0.35, 0.3, 0.0), 17.0,
                   mats["White"])


def add_sphere(mats, radius=0.3, location=(0.35, -0.3, 0.3)):
    """Smooth-shaded UV sphere with a Subdivision Surface modifier (1/1)."""
    mesh = bpy.data.meshes.new("Sphere")
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=8, radius=radius)
    bm.to_mesh(mesh)
    bm.free()
    mesh.shade_smooth()
    mesh.materials.append(mats["White"])
    obj = link_object("Sphere", mesh, location)
    subsurf = obj.modifiers.new("Subdivision", 'SUBSURF')
    subsurf.levels = 1
    subsurf.render_levels = 1
    return obj


def add_emitter_quad(material, center=(0.6, 0.99, 1.2), size=0.2):
    """Small emissive square parallel to the back wall, facing -Y."""
    cx, cy, cz = center
    origin = (cx - size / 2, cy, cz - size / 2)
    verts, faces, _ = planar_grid(origin, size * X, size * Z)
    return mesh_object("Emitter", verts, faces, material)


# --------------------------------------------------------------------------
# Lights and camera
# --------------------------------------------------------------------------

def add_area_light(shape='SQUARE'):
    """40 W area light (0.5 m) just below the ceiling, pointing down."""
    return add_light('AREA', 40.0, (0.0, 0.0, 1.98), shape=shape, size=0.5)


def add_point_light():
    """60 W point light of radius 0.05 m under the ceiling."""
    return add_light('POINT', 60.0, (0.0, 0.0, 1.7), shadow_soft_size=0.05)


def add_sun_light(elevation_deg=SUN_ELEVATION_DEG,
                  azimuth_deg=SUN_AZIMUTH_DEG):
    """Sun shining in through the left-wall window.

    The light travels towards +X (into the room), tilted down by
    ``elevation_deg`` and turned by ``azimuth_deg`` towards +Y.
    """
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    direction = Vector((math.cos(e) * math.cos(a), math.cos(e) * math.sin(a),
                        -math.sin(e)))
    window_center = Vector((-1.0, sum(WINDOW_Y) / 2, sum(WINDOW_Z) / 2))
    location = window_center - 1.5 * direction
    return add_light('SUN', 4.0, location, direction=direction,
                     angle=math.radians(2.0))


def add_camera(scene):
    """Perspective camera at CAMERA_LOCATION looking along +Y."""
    cam = bpy.data.cameras.new("Camera")
    cam.type = 'PERSP'
    cam.sensor_fit = 'AUTO'
    cam.sensor_width = SENSOR_WIDTH_MM
    half = math.radians(CAMERA_VFOV_DEG) / 2
    cam.lens = (SENSOR_WIDTH_MM / 2) / math.tan(half)
    cam.clip_start = 0.1
    cam.clip_end = 100.0
    obj = link_object("Camera", cam, CAMERA_LOCATION, (math.pi / 2, 0.0, 0.0))
    scene.camera = obj
    return obj


# --------------------------------------------------------------------------
# Scenes
# --------------------------------------------------------------------------

def cornell_base(world_color=(0.0, 0.0, 0.0), world_strength=0.0,
                 window=False, checker_floor=False):
    """Fresh scene with world, room, tall block and camera; returns mats."""
    scene = reset_scene()
    make_world(scene, world_color, world_strength)
    mats = make_base_materials()
    floor = None
    if checker_floor:
        floor = make_checker_material(make_checker_image())
    build_room(mats, floor_material=floor, window=window)
    add_tall_box(mats)
    add_camera(scene)
    return mats


def build_cornell_area():
    add_short_box(cornell_base())
    add_area_light('SQUARE')


def build_cornell_point():
    add_short_box(cornell_base())
    add_point_light()


def build_cornell_sun():
    add_short_box(cornell_base(world_color=(0.5, 0.7, 1.0),
                               world_strength=0.3, window=True))
    add_sun_light()


def build_cornell_textured():
    add_sphere(cornell_base(checker_floor=True))
    add_emitter_quad(make_material("Emitter", EMITTER_COLOR, EMITTER_COLOR,
                                   EMITTER_STRENGTH))
    add_area_light('DISK')


SCENES = {
    "cornell_area": build_cornell_area,
    "cornell_point": build_cornell_point,
    "cornell_sun": build_cornell_sun,
    "cornell_textured": build_cornell_textured,
}


if __name__ == "__main__":
    main(SCENES, __doc__)
