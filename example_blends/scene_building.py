"""What the example scripts build their scenes from, and how they write them.

Building: every scene starts from an empty factory-settings file set up the same way (``reset_scene``: metres,
256x256 at 100 %, Cycles on the CPU with 64 samples, 8 bounces and the Classic sampling pattern) and is made with
``bpy.data`` / ``bmesh`` only (no context-dependent operators except ``wm.read_factory_settings`` and
``wm.save_as_mainfile``): a World whose Background node sets colour and strength, pure diffuse Principled BSDF
materials (Roughness 1, Metallic 0, Specular IOR Level 0), mesh objects from vertex/face lists, lights.

Writing (``main``): each scene is saved, compressed, as ``<name>.blend`` into ``--out`` (default: this folder), by
the Blender that runs the script: 4.2, the oldest supported (``make examples``), since every later one opens a 4.2
file and 4.2 opens none written by 5.0. Blender does not write byte-identical files for identical content, so each
scene stores a fingerprint of the scripts that build it and Blender's version, and an existing file that already
holds the scene is left untouched; ``--force`` rewrites everything.
"""

import argparse
import hashlib
import json
import os
import sys

import bpy  # must come first: it makes bmesh/mathutils importable
from mathutils import Vector

HERE = os.path.dirname(os.path.abspath(__file__))
FINGERPRINT_KEY = "vpl_gi_example_fingerprint"
FINGERPRINT_ALIASES = os.path.join(HERE, "fingerprint_aliases.json")


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
    # Classic, as a new scene of 5.0 has it and the Cycles references were rendered with; a new 4.2 scene has
    # Automatic (blue noise)
    cycles.sampling_pattern = 'TABULATED_SOBOL'
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


# --------------------------------------------------------------------------
# Objects, meshes and lights
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


# --------------------------------------------------------------------------
# Writing the files
# --------------------------------------------------------------------------

def script_files():
    """The example scripts the running one is made of: itself and the modules it imports from this folder."""
    paths = {os.path.abspath(module.__file__) for module in list(sys.modules.values())
             if getattr(module, "__file__", None)}
    return sorted(path for path in paths if os.path.dirname(path) == HERE)


def fingerprint(name):
    """What scene ``name`` depends on: the bytes of the scripts that build it, Blender's version and the name.

    It is stored in the scene instead of comparing files: Blender cannot write byte-identical .blend files for
    identical content (random node identifiers, a time-seeded mesh field, uninitialised padding).
    """
    digest = hashlib.sha256()
    for path in script_files():
        with open(path, "rb") as f:
            digest.update(f.read())
        digest.update(b"\0")
    for part in (bpy.app.version_string, name):
        digest.update(part.encode())
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


def up_to_date(filepath, name, stamp):
    """Whether the file holds scene ``name`` as the scripts build it now.

    It does when it carries their fingerprint ``stamp``, or the fingerprint that fingerprint_aliases.json pairs
    with ``stamp``: the scripts changed since the file was written without changing what it holds.
    """
    stored = stored_fingerprint(filepath)
    with open(FINGERPRINT_ALIASES) as f:
        aliases = json.load(f)
    return stored == stamp or aliases.get(name) == {"scripts": stamp, "file": stored}


def save(filepath, stamp):
    """Stamp the scene and save the current file compressed (overwrites)."""
    bpy.context.scene[FINGERPRINT_KEY] = stamp
    bpy.context.preferences.filepaths.save_version = 0  # no .blend1 backup
    bpy.ops.wm.save_as_mainfile(filepath=filepath, compress=True,
                                check_existing=False, relative_remap=False)


def write_scene(filepath, name, build, force):
    """Build scene ``name`` and save it to ``filepath``, unless the file holds it already (and not ``force``)."""
    stamp = fingerprint(name)
    if not force and up_to_date(filepath, name, stamp):
        print(f"up to date: {filepath}")
        return
    build()
    save(filepath, stamp)
    print(f"wrote {filepath} ({os.path.getsize(filepath)} bytes)")


def main(scenes, description, argv=None):
    """Command line of an example script: write each of ``scenes`` (name -> build function) as ``<name>.blend``."""
    parser = argparse.ArgumentParser(description=description.splitlines()[0])
    parser.add_argument("--out", default=HERE,
                        help="output folder (default: %(default)s)")
    parser.add_argument("--force", action="store_true",
                        help="rewrite files even if they are up to date")
    args = parser.parse_args(argv)
    out_dir = os.path.abspath(args.out)
    os.makedirs(out_dir, exist_ok=True)
    for name, build in scenes.items():
        write_scene(os.path.join(out_dir, name + ".blend"), name, build, args.force)
