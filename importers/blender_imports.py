"""Blender scenes built around the public assets of ../shared/scenes that Blender's own importers read (glTF, USD,
OBJ + MTL, all shipped with ``bpy``), imported exactly as a user would, then given the camera, lights and world the
assets lack.

- ``helmet_hdri``: Khronos' DamagedHelmet (base colour, normal, metallic-roughness, emissive and occlusion maps) on a
  16 x 16 m grey ground under Poly Haven's Kloppenheim 05 HDR (a strong sun high in the sky), seen from the front
  right and above, so the sun's shadow falls on the ground in view.
- ``hotel_room``: Aaron Openshaw's hotel room (CC BY 4.0; 99K triangles in millimetres, scaled to metres; base-colour
  textures), a closed bedroom lit by a ceiling panel (an area light) and a bedside lamp (a sphere light), seen from the
  entrance corner towards the bed and the window wall. The world is black: no light enters the closed room.
- ``cornell_usd``: Pablo Delgado Kramer's Cornell box as a USD stage (``bpy.ops.wm.usd_import``: UsdPreviewSurface
  materials become Principled BSDFs, the stage's camera comes along), lit by its ceiling lamp, a glowing quad 1 mm
  under the ceiling.
- ``cornell_obj``: McGuire's CornellBox-Original OBJ + MTL (``bpy.ops.wm.obj_import``: the lamp an emissive ``Ke``
  material, a glowing quad 1 cm under the ceiling), seen by a camera placed as the original's (35 mm lens, 25 mm
  film, in front of the open side). Both worlds black.
"""
from __future__ import annotations

import os

import bpy
from mathutils import Matrix, Vector

HDRI = os.path.join("hdri_polyhaven", "kloppenheim_05_1k.hdr")


def _import(path: str) -> list:
    """The objects Blender's importer for ``path``'s kind of file (glTF, USD, OBJ) brings in."""
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path}: the file to import is missing")
    before = set(bpy.data.objects)
    if path.endswith((".usda", ".usdc", ".usd")):
        bpy.ops.wm.usd_import(filepath=path)
    elif path.endswith(".obj"):
        bpy.ops.wm.obj_import(filepath=path)
    else:
        bpy.ops.import_scene.gltf(filepath=path)
    return [o for o in bpy.data.objects if o not in before]


def _bounds(objects) -> tuple[Vector, Vector]:
    points = [o.matrix_world @ Vector(c) for o in objects if o.type == "MESH" for c in o.bound_box]
    lo = Vector([min(p[k] for p in points) for k in range(3)])
    hi = Vector([max(p[k] for p in points) for k in range(3)])
    return lo, hi


def _camera(scene, location: Vector, target: Vector, lens: float = 50.0, sensor: float = 36.0) -> None:
    data = bpy.data.cameras.new("Camera")
    data.lens, data.sensor_width = lens, sensor
    cam = bpy.data.objects.new("Camera", data)
    cam.location = location
    cam.rotation_euler = (target - location).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam


def _principled(name: str, colour, roughness: float):
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:
        mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    return mat


def _hdri_world(scene, path: str):
    world = bpy.data.worlds.new("HDRI")
    scene.world = world
    if world.node_tree is None:
        world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    env = nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(path, check_existing=True)
    env.image.pack()
    links.new(env.outputs["Color"], nodes["Background"].inputs["Color"])
    return world


def _black_world(scene):
    world = bpy.data.worlds.new("Black")
    scene.world = world
    if world.node_tree is None:
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    return world


def helmet_hdri(scene, source_dir: str, warnings: list) -> None:
    objects = _import(os.path.join(source_dir, "damaged_helmet_khronos", "DamagedHelmet.gltf"))
    lo, hi = _bounds(objects)
    centre = (lo + hi) / 2
    s = 8.0
    mesh = bpy.data.meshes.new("Ground")
    mesh.from_pydata([(-s, -s, lo.z), (s, -s, lo.z), (s, s, lo.z), (-s, s, lo.z)], [], [(0, 1, 2, 3)])
    mesh.materials.append(_principled("Ground", (0.5, 0.5, 0.5), 0.8))
    scene.collection.objects.link(bpy.data.objects.new("Ground", mesh))
    _hdri_world(scene, os.path.join(source_dir, HDRI))
    size = (hi - lo).length
    _camera(scene, centre + Vector((0.6, -1.6, 0.5)) * size, centre)


def hotel_room(scene, source_dir: str, warnings: list) -> None:
    objects = _import(os.path.join(source_dir, "hotel_room_openshaw", "hotel_room.glb"))
    for o in objects:
        if o.parent is None:
            o.matrix_world = Matrix.Scale(0.001, 4) @ o.matrix_world  # millimetres -> metres
    panel = bpy.data.lights.new("CeilingPanel", "AREA")
    panel.shape = "RECTANGLE"
    panel.size, panel.size_y = 1.2, 0.6
    panel.energy = 300.0
    panel.color = (1.0, 0.93, 0.85)
    obj = bpy.data.objects.new("CeilingPanel", panel)
    obj.location = (10.1, 8.25, 2.10)
    scene.collection.objects.link(obj)
    lamp = bpy.data.lights.new("BedsideLamp", "POINT")
    lamp.energy = 40.0
    lamp.shadow_soft_size = 0.08
    lamp.color = (1.0, 0.8, 0.6)
    obj = bpy.data.objects.new("BedsideLamp", lamp)
    obj.location = (12.95, 8.75, 0.95)
    scene.collection.objects.link(obj)
    _black_world(scene)
    _camera(scene, Vector((7.3, 10.7, 1.7)), Vector((12.0, 7.0, 0.7)), lens=20.0)


def cornell_usd(scene, source_dir: str, warnings: list) -> None:
    objects = _import(os.path.join(source_dir, "cornell_box_usd", "cornell-box_usdpreviewsurface.usda"))
    cameras = [o for o in objects if o.type == "CAMERA"]
    if not cameras:
        raise ValueError("cornell_box_usd: the stage holds no camera")
    scene.camera = cameras[0]
    _black_world(scene)


def cornell_obj(scene, source_dir: str, warnings: list) -> None:
    _import(os.path.join(source_dir, "cornell_box_mcguire", "CornellBox-Original.obj"))  # Y up -> Blender's Z up
    _black_world(scene)
    _camera(scene, Vector((0.0, -3.9, 1.0)), Vector((0.0, 0.0, 1.0)), lens=35.0, sensor=25.0)


BUILDERS = {"helmet_hdri": helmet_hdri, "hotel_room": hotel_room, "cornell_usd": cornell_usd,
            "cornell_obj": cornell_obj}
ASPECT = {"helmet_hdri": 1.0, "hotel_room": 0.75, "cornell_usd": 1.0, "cornell_obj": 1.0}  # height / width


def build(scene, source_dir: str, name: str) -> list[str]:
    """Fill the (reset) ``scene`` with ``name``'s objects, lights, world and camera; returns the warnings."""
    warnings: list[str] = []
    BUILDERS[name](scene, source_dir, warnings)
    bpy.ops.file.pack_all()  # the .blend stands alone, like the Mitsuba scenes' packed textures
    return warnings
