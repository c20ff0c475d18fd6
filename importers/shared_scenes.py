"""Plain scene data (``mitsuba.parse``, ``cornell_measured.parse``) -> a Blender scene, saved as a .blend.

Frames: Mitsuba is Y up, Blender Z up; every object gets ``matrix_world = C @ to_world`` with C the rotation
(x, y, z) -> (x, -z, y) (what Blender's OBJ importer does by default). Mitsuba's camera looks along its local +Z with
+X to the image's left, Blender's along -Z with +X to the right: its matrix is ``C @ to_world @ diag(-1, 1, -1)``.

Light units: Mitsuba gives radiance L (W/(m^2 sr)). An area emitter on a rectangle (a ``rectangle`` shape or a mesh
that is one planar rectangle) becomes a Blender area light, one-sided like Mitsuba's, with power
P = L * pi * A (Cycles' area light radiance is P / (pi A)). An area emitter on any other mesh becomes an emissive
material with Emission Strength = L (Cycles' emission strength is radiance), which Blender emits from both sides: a
warning says so. Point and spot intensity I (W/sr) becomes P = 4 pi I. An ``envmap`` becomes an Environment Texture
(rotated to match Mitsuba's lat-long convention); the Background colour under it holds the map's mean radiance.
"""
from __future__ import annotations

import hashlib
import math
import os

import bpy
import numpy as np
from mathutils import Matrix

from . import blender_imports, cornell_measured, mitsuba
from .wavefront import read_obj

FINGERPRINT_KEY = "vpl_gi_scene_fingerprint"
C = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])
CAMERA_FLIP = np.diag([-1.0, 1.0, -1.0, 1.0])
SOURCES = ("mitsuba.py", "cornell_measured.py", "wavefront.py", "blender_imports.py", "shared_scenes.py")

# name -> (folder under ../shared/scenes, file inside it, parser). "mitsuba-diffuse": every BSDF made Lambertian
# with its base colour (checkerboards by their mean colour), the variant on which VPL GI's diffuse-only methods and
# Cycles solve the same light transport. "import": imported by Blender's own importer (glTF,
# USD, OBJ) and staged by ``blender_imports``.
SCENES = {
    "cornell_measured": ("cornell_box_measured", cornell_measured.DATA, "cornell"),
    "cornell_bitterli": ("cornell_box_bitterli", "scene.xml", "mitsuba"),
    "veach_bidir": ("veach_bidir_bitterli", "scene.xml", "mitsuba"),
    "veach_mis": ("veach_mis_bitterli", "scene.xml", "mitsuba"),
    "veach_ajar": ("veach_ajar_bitterli_partial", "scene.xml", "mitsuba"),
    "veach_ajar_diffuse": ("veach_ajar_bitterli_partial", "scene.xml", "mitsuba-diffuse"),
    "living_room": ("living_room_bitterli", "scene.xml", "mitsuba"),
    "helmet_hdri": ("damaged_helmet_khronos", "DamagedHelmet.gltf", "import"),
    "hotel_room": ("hotel_room_openshaw", "hotel_room.glb", "import"),
    "cornell_usd": ("cornell_box_usd", "cornell-box_usdpreviewsurface.usda", "import"),
    "cornell_obj": ("cornell_box_mcguire", "CornellBox-Original.obj", "import"),
}
REFERENCE_IMAGES = {"cornell_bitterli": "TungstenRender.exr", "veach_bidir": "TungstenRender.exr",
                    "veach_mis": "TungstenRender.exr"}


def load(source_dir: str, name: str, width: int = mitsuba.DEFAULT_WIDTH) -> mitsuba.MitsubaScene:
    folder, file, kind = SCENES[name]
    path = os.path.join(source_dir, folder, file)
    if kind == "cornell":
        return cornell_measured.parse(os.path.dirname(path), width)
    scene = mitsuba.parse(path, width)
    if kind == "mitsuba-diffuse":
        lambertian(scene)
    missing = os.path.join(source_dir, folder, "MISSING.txt")
    if os.path.isfile(missing):
        scene.warnings.append(f"scene: {folder}/MISSING.txt: some meshes of the original scene are not in this copy "
                              f"(see the 'mesh file ... is missing' warnings)")
    return scene


def lambertian(scene: mitsuba.MitsubaScene) -> None:
    """Every material of ``scene`` made a pure diffuse one with its base colour; a checkerboard becomes its mean
    colour (VPL GI has no procedural textures), image textures stay."""
    done = {}
    for shape in scene.shapes:
        m = shape.material
        if id(m) not in done:
            tex = m.texture if m.texture is not None and m.texture.kind == "bitmap" else None
            done[id(m)] = mitsuba.Material(m.name, m.base_color, tex)
        shape.material = done[id(m)]
    scene.warnings.append("scene: diffuse variant: every BSDF replaced by a Lambertian one with its base colour "
                          "(metals, plastics and glass too; checkerboards by their mean colour)")


def fingerprint(source_dir: str, name: str, width: int) -> str:
    """The converter's code, the scene's XML/JSON, Blender's version and the width: what the .blend depends on."""
    digest = hashlib.sha256()
    here = os.path.dirname(os.path.abspath(__file__))
    for src in SOURCES:
        with open(os.path.join(here, src), "rb") as f:
            digest.update(f.read())
    folder, file, _ = SCENES[name]
    with open(os.path.join(source_dir, folder, file), "rb") as f:
        digest.update(f.read())
    digest.update(f"{bpy.app.version_string}\0{name}\0{width}".encode())
    return digest.hexdigest()


def stored_fingerprint(path: str) -> str | None:
    if not os.path.isfile(path):
        return None
    try:
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    except (RuntimeError, OSError):
        return None
    return bpy.data.scenes[0].get(FINGERPRINT_KEY) if bpy.data.scenes else None


# --- building ------------------------------------------------------------------------------------------------------

def _reset(width: int, height: int, samples: int, bounces: int):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.unit_settings.system = "METRIC"
    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y = width, height
    r.resolution_percentage = 100
    c = scene.cycles
    c.device = "CPU"
    c.samples = samples
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.seed = 0
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = bounces
    c.transparent_max_bounces = 8
    c.volume_bounces = 0
    c.caustics_reflective = c.caustics_refractive = True
    return scene


def _matrix(m: np.ndarray) -> Matrix:
    return Matrix([list(row) for row in m])


def _image(path: str, warnings: list, owner: str):
    if not os.path.isfile(path):
        warnings.append(f"{owner}: texture file {path} is missing; using the base colour")
        return None
    image = bpy.data.images.load(path, check_existing=True)
    if not path.lower().endswith((".exr", ".hdr")):
        image.colorspace_settings.name = "sRGB"
    image.pack()
    return image


def make_material(m: mitsuba.Material, warnings: list, emission=None):
    mat = bpy.data.materials.new(m.name)
    if mat.node_tree is None:
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    i = bsdf.inputs
    i["Base Color"].default_value = (*m.base_color, 1.0)
    i["Roughness"].default_value = m.roughness
    i["Metallic"].default_value = m.metallic
    i["Specular IOR Level"].default_value = m.specular
    i["IOR"].default_value = m.ior
    i["Transmission Weight"].default_value = m.transmission
    mat.diffuse_color = (*m.base_color, 1.0)
    if emission is not None:
        peak = float(max(np.max(emission), 1e-12))
        i["Emission Color"].default_value = (*(np.asarray(emission) / peak), 1.0)
        i["Emission Strength"].default_value = peak
    tex = m.texture
    if tex is not None and tex.kind == "bitmap":
        image = _image(tex.filename, warnings, tex.element or f"material {m.name!r}")
        if image is not None:
            node = nodes.new("ShaderNodeTexImage")
            node.image = image
            node.interpolation = "Linear"
            links.new(node.outputs["Color"], i["Base Color"])
    elif tex is not None and tex.kind == "checkerboard":
        # Mitsuba: colour0 where frac(u') and frac(v') are on the same side of 1/2, u' = to_uv(u); Blender's
        # Checker flips colour at every integer of 2 u', so it gets twice the to_uv scale.
        coords = nodes.new("ShaderNodeTexCoord")
        mapping = nodes.new("ShaderNodeMapping")
        mapping.inputs["Scale"].default_value = (2 * tex.uv_scale[0], 2 * tex.uv_scale[1], 1.0)
        checker = nodes.new("ShaderNodeTexChecker")
        checker.inputs["Scale"].default_value = 1.0
        checker.inputs["Color1"].default_value = (*tex.color0, 1.0)
        checker.inputs["Color2"].default_value = (*tex.color1, 1.0)
        links.new(coords.outputs["UV"], mapping.inputs["Vector"])
        links.new(mapping.outputs["Vector"], checker.inputs["Vector"])
        links.new(checker.outputs["Color"], i["Base Color"])
    return mat


def _primitive(kind: str):
    """(vertices, faces, smooth) of Mitsuba's primitives in their local frame."""
    if kind == "rectangle":
        return np.array([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], float), [[0, 1, 2, 3]], False
    if kind == "cube":
        v = np.array([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
        return v, faces, False
    if kind == "disk":
        n = 64
        t = np.linspace(0, 2 * np.pi, n, endpoint=False)
        return np.stack([np.cos(t), np.sin(t), np.zeros(n)], 1), [list(range(n))], False
    if kind == "sphere":
        nu, nv = 64, 32
        verts = [(0, 0, -1)]
        for j in range(1, nv):
            th = np.pi * j / nv - np.pi / 2
            for k in range(nu):
                ph = 2 * np.pi * k / nu
                verts.append((np.cos(th) * np.cos(ph), np.cos(th) * np.sin(ph), np.sin(th)))
        verts.append((0, 0, 1))
        faces = []
        ring = lambda j, k: 1 + (j - 1) * nu + k % nu  # noqa: E731
        for k in range(nu):
            faces.append([0, ring(1, k + 1), ring(1, k)])
            faces.append([len(verts) - 1, ring(nv - 1, k), ring(nv - 1, k + 1)])
        for j in range(1, nv - 1):
            for k in range(nu):
                faces.append([ring(j, k), ring(j, k + 1), ring(j + 1, k + 1), ring(j + 1, k)])
        return np.array(verts, float), faces, True
    raise ValueError(kind)


def _mesh(name: str, positions, face_sizes, corner_vertex, uv=None, normals=None, smooth=False):
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(positions))
    mesh.vertices.foreach_set("co", np.asarray(positions, np.float32).ravel())
    mesh.loops.add(len(corner_vertex))
    mesh.loops.foreach_set("vertex_index", np.asarray(corner_vertex, np.int32))
    mesh.polygons.add(len(face_sizes))
    starts = np.concatenate([[0], np.cumsum(face_sizes)[:-1]]).astype(np.int32)
    mesh.polygons.foreach_set("loop_start", starts)
    mesh.polygons.foreach_set("use_smooth", np.full(len(face_sizes), smooth or normals is not None))
    if uv is not None:
        layer = mesh.uv_layers.new(name="UVMap")
        layer.data.foreach_set("uv", np.asarray(uv, np.float32).ravel())
    mesh.update()
    mesh.validate(clean_customdata=False)
    if normals is not None and len(mesh.loops) == len(normals):
        n = np.asarray(normals, np.float64)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        mesh.normals_split_custom_set(n.astype(np.float32).tolist())
    return mesh


def _rectangle(points: np.ndarray):
    """(centre, edge u, edge v, normal) of four points that form a planar rectangle in order, else None."""
    if len(points) != 4:
        return None
    p = np.asarray(points, np.float64)
    u, v = p[1] - p[0], p[3] - p[0]
    lu, lv = np.linalg.norm(u), np.linalg.norm(v)
    if lu < 1e-9 or lv < 1e-9:
        return None
    tol = 1e-4 * max(lu, lv)
    if abs(np.dot(u, v)) > tol * max(lu, lv) or np.linalg.norm(p[2] - (p[0] + u + v)) > tol:
        return None
    n = np.cross(u, v)
    return p.mean(axis=0), u, v, n / np.linalg.norm(n)


def _area_light(scene, name, centre, u, v, normal, radiance, visible=True):
    """A one-sided rectangular area light emitting radiance along ``normal`` (all in Blender's frame)."""
    area = float(np.linalg.norm(u) * np.linalg.norm(v))
    peak = float(max(np.max(radiance), 1e-12))
    light = bpy.data.lights.new(name, "AREA")
    light.shape = "RECTANGLE"
    light.size, light.size_y = float(np.linalg.norm(u)), float(np.linalg.norm(v))
    light.color = tuple(np.asarray(radiance) / peak)
    light.energy = peak * math.pi * area
    ex, ez = u / np.linalg.norm(u), -normal  # Blender's area light emits along its local -Z
    ey = np.cross(ez, ex)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = ex, ey, ez, centre
    obj = bpy.data.objects.new(name, light)
    obj.matrix_world = _matrix(m)
    obj.visible_camera = visible
    scene.collection.objects.link(obj)
    return obj


def _shape_geometry(shape: mitsuba.Shape):
    """(positions, face sizes, corner vertices, uv, normals, smooth) in the shape's local frame."""
    if shape.kind == "obj":
        obj = read_obj(shape.filename)
        normals = None if shape.face_normals else obj.corner_normal
        return obj.positions, obj.face_sizes, obj.corner_vertex, obj.corner_uv, normals, not shape.face_normals
    if shape.kind == "polygons":
        verts, faces = shape.polygons
        verts = np.asarray(verts, np.float64)
        smooth = False
    else:
        verts, faces, smooth = _primitive(shape.kind)
        if shape.kind == "rectangle":  # Mitsuba's rectangle uv: (x, y) in [-1, 1] -> [0, 1]
            uv = (verts[np.array(faces[0])][:, :2] + 1) / 2
            return verts, np.array([4], np.int32), np.array(faces[0], np.int32), uv, None, False
    sizes = np.array([len(f) for f in faces], np.int32)
    return verts, sizes, np.concatenate([np.asarray(f, np.int32) for f in faces]), None, None, smooth


def _add_shape(scene, shape: mitsuba.Shape, materials: dict, warnings: list) -> None:
    positions, sizes, corners, uv, normals, smooth = _shape_geometry(shape)
    to_blender = C @ shape.matrix
    if shape.radiance is not None and np.max(shape.radiance) > 0:
        if len(sizes) == 1 and sizes[0] == 4:
            world = np.c_[positions[corners], np.ones(4)] @ to_blender.T
            rect = _rectangle(world[:, :3])
            if rect is not None:
                centre, u, v, n = rect
                if normals is not None and np.dot(np.mean(normals, 0) @ np.linalg.inv(to_blender[:3, :3]), n) < 0:
                    n = -n  # the file's normal decides the emitting side, as in Mitsuba
                _area_light(scene, shape.name, centre, u, v, n, shape.radiance)
                return
        warnings.append(f"{shape.element}: area emitter on a mesh that is not one rectangle: converted to an "
                        f"emissive material (strength = radiance), which Blender emits from both sides "
                        f"(Mitsuba: the front side only)")
        key = ("emissive", id(shape.material), tuple(shape.radiance))
        if key not in materials:
            materials[key] = make_material(shape.material, warnings, emission=shape.radiance)
        mat = materials[key]
    else:
        key = id(shape.material)
        if key not in materials:
            materials[key] = make_material(shape.material, warnings)
        mat = materials[key]
    mesh = _mesh(shape.name, positions, sizes, corners, uv, normals, smooth)
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(shape.name, mesh)
    obj.matrix_world = _matrix(to_blender)
    scene.collection.objects.link(obj)


def _camera(scene, cam: mitsuba.Camera, warnings: list) -> None:
    m = cam.matrix.copy()
    scale = np.linalg.norm(m[:3, :3], axis=0)
    m[:3, :3] /= scale
    if np.linalg.det(m[:3, :3]) < 0:
        warnings.append(f"{cam.element}: its to_world is mirrored; Blender cameras cannot mirror, the image is flipped "
                        "left to right against the source")
        m[:3, 0] *= -1
    data = bpy.data.cameras.new("Camera")
    data.sensor_width = data.sensor_height = 36.0
    w, h = cam.source_size
    axis = cam.fov_axis
    if axis == "smaller":
        axis = "x" if w <= h else "y"
    elif axis == "larger":
        axis = "x" if w >= h else "y"
    half = math.tan(math.radians(cam.fov_deg) / 2)
    if axis == "diagonal":
        half, axis = half * w / math.hypot(w, h), "x"
    data.sensor_fit = "HORIZONTAL" if axis == "x" else "VERTICAL"
    data.lens = 18.0 / half
    data.clip_start, data.clip_end = max(cam.near, 1e-4), max(cam.far, cam.near * 10)
    obj = bpy.data.objects.new("Camera", data)
    obj.matrix_world = _matrix(C @ m @ CAMERA_FLIP)
    scene.collection.objects.link(obj)
    scene.camera = obj


def envmap_rotation(to_world: np.ndarray) -> np.ndarray:
    """3x3 rotation R such that Blender's equirectangular lookup of R @ d (d a Blender world direction) reads the
    texel Mitsuba's envmap with ``to_world`` reads for the same direction."""
    r = to_world[:3, :3] / np.linalg.norm(to_world[:3, :3], axis=0)
    c = C[:3, :3]
    rot_z = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # +90 degrees about Z
    return rot_z @ c @ np.linalg.inv(r) @ c.T


def _world(scene, env: mitsuba.Environment | None, warnings: list) -> None:
    world = bpy.data.worlds.new("World")
    if world.node_tree is None:
        world.use_nodes = True
    scene.world = world
    nodes, links = world.node_tree.nodes, world.node_tree.links
    bg = nodes["Background"]
    if env is None:
        bg.inputs["Color"].default_value = (0, 0, 0, 1)
        bg.inputs["Strength"].default_value = 0.0
        return
    if env.kind == "constant":
        peak = float(max(np.max(env.radiance), 1e-12))
        bg.inputs["Color"].default_value = (*(env.radiance / peak), 1.0)
        bg.inputs["Strength"].default_value = peak
        return
    image = _image(env.filename, warnings, env.element)
    if image is None:
        bg.inputs["Strength"].default_value = 0.0
        return
    w, h = image.size
    px = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(px)
    rgb = px.reshape(h, w, image.channels)[..., :3].astype(np.float64)
    rows = (np.arange(h) + 0.5) / h * np.pi  # Blender's rows go bottom to top; sin is symmetric
    weight = np.sin(rows)[:, None]
    mean = (rgb * weight[..., None]).sum((0, 1)) / (weight.sum() * w)
    # the unlinked Color value (unused once linked) keeps the map's mean radiance for anyone who unlinks the map
    bg.inputs["Color"].default_value = (*mean, 1.0)
    coords = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    mapping.vector_type = "VECTOR"
    mapping.inputs["Rotation"].default_value = _matrix(envmap_rotation(env.matrix)).to_euler("XYZ")
    tex = nodes.new("ShaderNodeTexEnvironment")
    tex.image = image
    tex.interpolation = "Linear"
    links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = env.scale
    world["vpl_gi_mean_radiance"] = [float(x) for x in mean * env.scale]


def _lights(scene, data: mitsuba.MitsubaScene) -> None:
    for i, light in enumerate(data.lights):
        peak = float(max(np.max(light.intensity), 1e-12))
        kind = "POINT" if isinstance(light, mitsuba.PointLight) else "SPOT"
        lamp = bpy.data.lights.new(f"{kind.title()}{i}", kind)
        lamp.color = tuple(np.asarray(light.intensity) / peak)
        lamp.energy = 4 * math.pi * peak  # Cycles: intensity = P / (4 pi) W/sr
        lamp.shadow_soft_size = 0.0
        obj = bpy.data.objects.new(lamp.name, lamp)
        if kind == "POINT":
            m = np.eye(4)
            m[:3, 3] = light.position
        else:
            lamp.spot_size = math.radians(2 * light.cutoff_deg)
            lamp.spot_blend = max(0.0, min(1.0, (light.cutoff_deg - light.beam_width_deg) / light.cutoff_deg))
            m = light.matrix @ np.diag([1.0, -1.0, -1.0, 1.0])  # Mitsuba shines along +Z, Blender along -Z
            m[:3, :3] /= np.linalg.norm(m[:3, :3], axis=0)
        obj.matrix_world = _matrix(C @ m)
        scene.collection.objects.link(obj)


def build(data: mitsuba.MitsubaScene, samples: int = 64):
    """Build ``data`` into the current (reset) Blender file; returns the scene and the warnings."""
    if data.camera is None:
        raise mitsuba.MitsubaError(f"{data.path}: no camera to convert")
    warnings = list(data.warnings)
    scene = _reset(data.camera.width, data.camera.height, samples, min(data.max_bounces or 8, 16))
    materials: dict = {}
    for shape in data.shapes:
        _add_shape(scene, shape, materials, warnings)
    _lights(scene, data)
    _world(scene, data.environment, warnings)
    _camera(scene, data.camera, warnings)
    return scene, warnings


def convert(source_dir: str, name: str, out_path: str, width: int = mitsuba.DEFAULT_WIDTH,
            force: bool = False) -> tuple[bool, list[str]]:
    """Write ``out_path`` from ``source_dir``'s scene ``name`` unless an up-to-date one is there; returns
    (written, warnings)."""
    stamp = fingerprint(source_dir, name, width)
    if not force and stored_fingerprint(out_path) == stamp:
        return False, []
    if SCENES[name][2] == "import":
        scene = _reset(width, round(width * blender_imports.ASPECT[name]), 64, 8)
        warnings = blender_imports.build(scene, source_dir, name)
    else:
        scene, warnings = build(load(source_dir, name, width))
    scene[FINGERPRINT_KEY] = stamp
    scene["vpl_gi_source"] = os.path.join(SCENES[name][0], SCENES[name][1])
    scene["vpl_gi_import_warnings"] = warnings
    os.makedirs(os.path.dirname(os.path.abspath(out_path)), exist_ok=True)
    bpy.context.preferences.filepaths.save_version = 0
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(out_path), compress=True, check_existing=False,
                                relative_remap=False)
    return True, warnings
