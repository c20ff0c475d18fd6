"""Build the VPL GI example scenes (Cornell box variants) from scratch.

Run with the project's bpy-enabled Python (Blender as a Python module):

    .venv/bin/python example_blends/make_examples.py [--out DIR]

Every scene is built deterministically from an empty factory-settings file
using only ``bpy.data`` / ``bmesh`` (no context-dependent operators except
``wm.read_factory_settings`` and ``wm.save_as_mainfile``) and saved,
compressed, as ``<name>.blend`` into ``DIR`` (default: this script's folder).
Only those files are written.  Blender does not write byte-identical files
for identical content, so each scene stores a fingerprint (hash of this
script + Blender version) and an existing file whose fingerprint matches is
left untouched; ``--force`` rewrites everything.

Scene conventions: metres, Z up, 256x256 at 100 %, Cycles (64 samples,
8 bounces), a World whose Background node sets colour and strength, and a
perspective camera at (0, -3.9, 1) looking along +Y into the open front of
a 2 m Cornell box spanning x, y in [-1, 1], z in [0, 2].  All materials are
pure diffuse Principled BSDFs (Roughness 1, Metallic 0, Specular IOR Level 0).
"""

import argparse
import hashlib
import math
import os
import sys

import bpy  # must come first: it makes bmesh/mathutils importable
import bmesh
from mathutils import Vector

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
# Scene / render settings
# --------------------------------------------------------------------------

def reset_scene():
    """Start from an empty factory file and configure units and rendering."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.unit_settings.system = 'METRIC'
    scene.unit_settings.length_unit = 'METERS'
    scene.unit_settings.scale_length = 1.0

    render = scene.render
    render.engine = 'CYCLES'
    render.resolution_x = 256
    render.resolution_y = 256
    render.resolution_percentage = 100

    cycles = scene.cycles
    cycles.device = 'CPU'
    cycles.samples = 64
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.seed = 0
    cycles.max_bounces = 8
    cycles.diffuse_bounces = 8
    cycles.glossy_bounces = 8
    cycles.transmission_bounces = 0
    cycles.volume_bounces = 0
    cycles.transparent_max_bounces = 8
    cycles.caustics_reflective = True
    cycles.caustics_refractive = True
    return scene


def make_world(scene, color, strength):
    """Create the World with a Background node of the given colour/strength."""
    world = bpy.data.worlds.new("World")
    if world.node_tree is None:  # Blender < 5.0 needs use_nodes
        world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*color, 1.0)
    background.inputs["Strength"].default_value = strength
    scene.world = world
    return world


# --------------------------------------------------------------------------
# Materials
# --------------------------------------------------------------------------

def make_material(name, base_color, emission_color=None,
                  emission_strength=0.0):
    """Pure diffuse Principled BSDF material, optionally emissive."""
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:  # Blender < 5.0 needs use_nodes
        mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*base_color, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Metallic"].default_value = 0.0
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    if emission_color is not None:
        bsdf.inputs["Emission Color"].default_value = (*emission_color, 1.0)
        bsdf.inputs["Emission Strength"].default_value = emission_strength
    mat.diffuse_color = (*base_color, 1.0)  # viewport colour
    return mat


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
# Mesh helpers
# --------------------------------------------------------------------------

def link_object(name, data, location=(0.0, 0.0, 0.0),
                rotation=(0.0, 0.0, 0.0)):
    """Create an object for ``data`` and link it into the scene collection."""
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    obj.rotation_euler = rotation
    bpy.context.scene.collection.objects.link(obj)
    return obj


def mesh_object(name, verts, faces, material, uvs=None,
                location=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0)):
    """Build a mesh object from vertex/face lists (optional per-vertex UVs)."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in verts], [], faces)
    if uvs is not None:
        uv_layer = mesh.uv_layers.new(name="UVMap")
        for loop in mesh.loops:
            uv_layer.data[loop.index].uv = uvs[loop.vertex_index]
    mesh.validate()
    mesh.update()
    mesh.materials.append(material)
    return link_object(name, mesh, location, rotation)


def planar_grid(origin, u_vec, v_vec, u_breaks=(0.0, 1.0),
                v_breaks=(0.0, 1.0), holes=()):
    """Vertices, quads and UVs of a planar rectangle cut into a grid.

    Points are ``origin + u * u_vec + v * v_vec`` for u in ``u_breaks`` and
    v in ``v_breaks`` (fractions 0..1); the face normal is
    ``u_vec x v_vec``.  ``holes`` lists (i, j) grid cells left out.
    """
    origin = Vector(origin)
    verts, uvs = [], []
    for v in v_breaks:
        for u in u_breaks:
            verts.append(origin + u * Vector(u_vec) + v * Vector(v_vec))
            uvs.append((u, v))
    n_u = len(u_breaks)
    faces = []
    for j in range(len(v_breaks) - 1):
        for i in range(n_u - 1):
            if (i, j) in holes:
                continue
            a = j * n_u + i
            faces.append((a, a + 1, a + 1 + n_u, a + n_u))
    return verts, faces, uvs


def box_geometry(size_x, size_y, size_z):
    """Closed box centred on the origin in x/y, base at z=0, normals out."""
    hx, hy = size_x / 2.0, size_y / 2.0
    verts = [(-hx, -hy, 0.0), (hx, -hy, 0.0), (hx, hy, 0.0), (-hx, hy, 0.0),
             (-hx, -hy, size_z), (hx, -hy, size_z), (hx, hy, size_z),
             (-hx, hy, size_z)]
    faces = [(0, 3, 2, 1), (4, 5, 6, 7),  # bottom, top
             (0, 1, 5, 4), (1, 2, 6, 5),  # front (-y), right (+x)
             (2, 3, 7, 6), (3, 0, 4, 7)]  # back (+y), left (-x)
    return verts, faces


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

def add_light(light_type, energy, location, direction=(0.0, 0.0, -1.0),
              **settings):
    """Create the scene's single light 'Light' pointing along ``direction``."""
    light = bpy.data.lights.new("Light", light_type)
    light.energy = energy
    light.color = (1.0, 1.0, 1.0)
    for key, value in settings.items():
        setattr(light, key, value)
    rotation = Vector(direction).to_track_quat('-Z', 'Y').to_euler()
    return link_object("Light", light, location, rotation)


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


FINGERPRINT_KEY = "vpl_gi_example_fingerprint"


def fingerprint(name):
    """Identify what produced a scene: this script's bytes + Blender version.

    Blender cannot write byte-identical .blend files for identical content
    (random node identifiers, a time-seeded mesh field, uninitialised
    padding), so instead of rewriting unchanged scenes the fingerprint is
    stored in the scene and an existing file is only replaced when it differs.
    """
    with open(os.path.abspath(__file__), "rb") as f:
        source = f.read()
    digest = hashlib.sha256()
    for part in (source, bpy.app.version_string.encode(), name.encode()):
        digest.update(part)
        digest.update(b"\0")
    return digest.hexdigest()


def stored_fingerprint(filepath):
    """Fingerprint saved in an existing .blend, or None."""
    if not os.path.isfile(filepath):
        return None
    try:
        bpy.ops.wm.open_mainfile(filepath=filepath, load_ui=False)
    except RuntimeError:
        return None
    scene = bpy.data.scenes[0] if bpy.data.scenes else None
    return scene.get(FINGERPRINT_KEY) if scene is not None else None


def save(filepath, stamp):
    """Stamp the scene and save the current file compressed (overwrites)."""
    bpy.context.scene[FINGERPRINT_KEY] = stamp
    bpy.context.preferences.filepaths.save_version = 0  # no .blend1 backup
    bpy.ops.wm.save_as_mainfile(filepath=filepath, compress=True,
                                check_existing=False, relative_remap=False)


def main(argv=None):
    default_out = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=default_out,
                        help="output folder (default: %(default)s)")
    parser.add_argument("--force", action="store_true",
                        help="rewrite files even if they are up to date")
    args = parser.parse_args(argv)
    out_dir = os.path.abspath(args.out)
    os.makedirs(out_dir, exist_ok=True)
    for name, build in SCENES.items():
        path = os.path.join(out_dir, name + ".blend")
        stamp = fingerprint(name)
        if not args.force and stored_fingerprint(path) == stamp:
            print(f"up to date: {path}")
            continue
        build()
        save(path, stamp)
        print(f"wrote {path} ({os.path.getsize(path)} bytes)")


if __name__ == "__main__":
    main(sys.argv[1:])
