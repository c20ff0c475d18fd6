"""Blender scene -> engine ``Scene``: the one place that reads geometry, materials, lights, world and camera.

Reads the evaluated depsgraph, so modifiers, instances, curves and text arrive as triangles; objects that are
hidden from render are not in a render depsgraph and are skipped. Bulk data goes through ``foreach_get`` into
numpy. Anything the engine cannot represent is approximated with one warning that names the datablock; the features
it does not render (portals, volumes, hair, point clouds, holdouts, ...) are left out or approximated by
``unsupported``, one warning per case.
"""
from __future__ import annotations

import math

import numpy as np

from ...vpl_addon.core.camera import Camera, view_window
from ...vpl_addon.core.scene import Environment, Scene
from ...vpl_addon.lights import AreaLight, PointLight, SpotLight, SunLight
from .shader_nodes import MaterialTable, image_pixels, output_shader
from .unsupported import Unsupported
from .world_bake import BakeError, baked_world

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
ACTIVE_UV = ""  # ``extract``'s bake UV map: each mesh's own render UV map


class ExtractionError(RuntimeError):
    """The scene cannot be rendered; the message names the object or setting at fault."""


def _array(collection, attr, width, dtype=np.float32):
    out = np.empty(len(collection) * width, dtype)
    collection.foreach_get(attr, out)
    return out.reshape(-1, width) if width > 1 else out


def _matrix(m) -> np.ndarray:
    return np.array([list(row) for row in m], np.float64)


def _mesh_arrays(obj, matrix, materials: MaterialTable, object_index: int, warnings: list[str],
                 bake_uv: str | None = None):
    """(triangles, normals, uvs, material ids, object ids, tangents or None, colours or None, bake UVs or None)
    of a geometry object in world space; the bake UVs those of UV map ``bake_uv`` (``ACTIVE_UV``: the one
    rendering uses), None when not asked for or the mesh has no UV map."""
    mesh = obj.to_mesh()
    try:
        mesh.calc_loop_triangles()
        tris = mesh.loop_triangles
        if len(tris) == 0:
            return None
        co = _array(mesh.vertices, "co", 3).astype(np.float64)
        vidx = _array(tris, "vertices", 3, np.int32)
        lidx = _array(tris, "loops", 3, np.int32)
        mat_local = _array(tris, "material_index", 1, np.int32)
        m = _matrix(matrix)
        world = co @ m[:3, :3].T + m[:3, 3]
        normal_matrix = np.linalg.inv(m[:3, :3]).T if abs(np.linalg.det(m[:3, :3])) > 1e-300 else np.eye(3)
        corner_n = _array(mesh.corner_normals, "vector", 3).astype(np.float64) @ normal_matrix.T
        triangles = world[vidx]
        normals = corner_n[lidx]
        mirrored = np.linalg.det(m[:3, :3]) < 0
        if mirrored:  # keep counter-clockwise = front
            triangles = triangles[:, ::-1]
            normals = normals[:, ::-1]
            lidx = lidx[:, ::-1]
        slots = [materials.id_of(s.material) for s in obj.material_slots] or [0]
        slot_ids = np.array(slots, np.int32)
        mat = slot_ids[np.clip(mat_local, 0, len(slot_ids) - 1)]
        uvs = _uvs(obj, mesh, materials, slots, mat, lidx, warnings)
        colors = _colors(obj, mesh, materials, slots, mat, lidx, vidx, warnings)
        tangents = None
        if any(materials.normal_mapped(i) for i in slots):
            tangents = _tangents(obj, mesh, materials, slots, m, mirrored, warnings)
            tangents = None if tangents is None else tangents[lidx]
        baked = None
        if bake_uv is not None and uv_layer(mesh, bake_uv or None) is not None:
            baked = _array(uv_layer(mesh, bake_uv or None).data, "uv", 2)[lidx]
        return triangles, normals, uvs, mat, np.full(len(tris), object_index, np.int32), tangents, colors, baked
    finally:
        obj.to_mesh_clear()


def uv_layer(mesh, name: str | None):
    """The UV layer named ``name``, or the one rendering uses by default (None if the mesh has none)."""
    layers = mesh.uv_layers
    if name is not None and name in layers:
        return layers[name]
    return next((layer for layer in layers if layer.active_render), layers.active)


def _uvs(obj, mesh, materials: MaterialTable, slots: list[int], mat, lidx, warnings) -> np.ndarray:
    """(T,3,2) UVs: each material's triangles in the UV map its textures name."""
    uvs = np.zeros((len(lidx), 3, 2), np.float32)
    read: dict[str, np.ndarray] = {}  # each layer read once, however many materials use it
    for i in sorted(set(slots)):
        name = materials.uv_map.get(i)
        layer = uv_layer(mesh, name)
        if layer is None:
            if materials.images.get(i):
                warnings.append(f"object {obj.name!r}: it has no UV map, so material "
                                f"{materials.rows[i - 1]['name']!r} reads texture {materials.images[i][0]!r} at UV "
                                f"(0, 0)")
            continue
        if name is not None and layer.name != name:
            warnings.append(f"object {obj.name!r}: no UV map {name!r} (material {materials.rows[i - 1]['name']!r}); "
                            f"using {layer.name!r}")
        if layer.name not in read:
            read[layer.name] = _array(layer.data, "uv", 2)
        rows = mat == i
        uvs[rows] = read[layer.name][lidx[rows]]
    return uvs


def _colors(obj, mesh, materials: MaterialTable, slots: list[int], mat, lidx, vidx, warnings) -> np.ndarray | None:
    """(T,3,3) linear RGB per corner of the colour attribute each material reads (its Color Attribute node's, or
    the mesh's render colour for an unnamed one), None when no material here reads one. A missing attribute is
    black, as Cycles renders it, with a warning naming it."""
    wanted = {i: materials.color_attribute[i] for i in set(slots) if i in materials.color_attribute}
    if not wanted:
        return None
    attributes = mesh.color_attributes
    colors = np.zeros((len(lidx), 3, 3), np.float32)
    for i, name in wanted.items():
        if not name:
            index = attributes.render_color_index
            name = attributes[index].name if 0 <= index < len(attributes) else ""
        attribute = attributes.get(name) if name else None
        if attribute is None or attribute.domain not in ("POINT", "CORNER"):
            warnings.append(f"object {obj.name!r}: material {materials.rows[i - 1]['name']!r} reads colour "
                            f"attribute {name or '(the default)'!r}, which the mesh does not have (per point or "
                            f"corner); black, as in Cycles")
            continue
        values = _array(attribute.data, "color", 4)[:, :3]  # scene-linear for byte and float colours alike
        rows = mat == i
        colors[rows] = values[(lidx if attribute.domain == "CORNER" else vidx)[rows]]
    return colors


def _tangents(obj, mesh, materials: MaterialTable, slots: list[int], m: np.ndarray, mirrored: bool, warnings):
    """(loops,4) MikkTSpace tangents (world xyz, bitangent sign) of the UV map of the first normal-mapped
    material, as Cycles' Normal Map node uses them; None when Blender cannot make them (the engine then derives
    them per triangle from the UVs)."""
    name = next(materials.uv_map.get(i) for i in slots if materials.normal_mapped(i))
    layer = uv_layer(mesh, name)
    if layer is None:
        return None
    try:
        mesh.calc_tangents(uvmap=layer.name)
    except RuntimeError as e:  # n-gons: Blender makes tangents for triangles and quads only
        warnings.append(f"object {obj.name!r}: no tangents for its normal map ({e}); using per-triangle ones")
        return None
    t = _array(mesh.loops, "tangent", 3).astype(np.float64) @ m[:3, :3].T
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
    sign = _array(mesh.loops, "bitangent_sign", 1).astype(np.float64) * (-1.0 if mirrored else 1.0)
    return np.concatenate([t, sign[:, None]], axis=1)


def _without(arrays, material_ids: list[int]):
    """``arrays`` of ``_mesh_arrays`` without the triangles of ``material_ids`` (None when none is left)."""
    if arrays is None or not material_ids:
        return arrays
    keep = ~np.isin(arrays[3], material_ids)
    return tuple(None if a is None else a[keep] for a in arrays) if keep.any() else None


def light_nodes_used(data) -> bool:
    """Whether a light's shader nodes change its light: switched on and other than the tree Blender makes for a new
    light (a white Emission of Strength 1 into the Light Output), which every light of Blender 5.2 has, with
    ``use_nodes`` reading True."""
    if not getattr(data, "use_nodes", False) or getattr(data, "node_tree", None) is None:
        return False
    shader = output_shader(data)
    if shader is None or shader.type != "EMISSION":
        return True
    color, strength = shader.inputs["Color"], shader.inputs["Strength"]
    return color.is_linked or strength.is_linked or tuple(color.default_value[:3]) != (1.0, 1.0, 1.0) \
        or strength.default_value != 1.0


def _light(obj, matrix, warnings):
    data = obj.data
    m = _matrix(matrix)
    pos = m[:3, 3]
    down = -m[:3, 2]
    name = obj.name
    if getattr(data, "use_temperature", False):
        warnings.append(f"light {name!r}: colour temperature is not supported; using its colour alone")
    if light_nodes_used(data):
        warnings.append(f"light {name!r}: light nodes are not supported; using colour and power alone")
    power = np.array(data.color[:3], np.float64) * data.energy * 2.0 ** getattr(data, "exposure", 0.0)
    normalize = getattr(data, "normalize", True)  # off: power is radiance-like, not divided by the light's size
    if data.type in {"POINT", "SPOT"}:
        radius = data.shadow_soft_size
        if not normalize:  # Cycles: intensity P / pi (radius 0) or radiance P / pi (radius R)
            power = power * (4.0 * math.pi * radius * radius if radius > 0 else 4.0)
        soft = getattr(data, "use_soft_falloff", True)
        if data.type == "POINT":
            light = PointLight(name, pos, power, radius=radius, soft_falloff=soft)
        else:
            light = SpotLight(name, pos, power, radius=radius, soft_falloff=soft, direction=down,
                              spot_size=data.spot_size, spot_blend=data.spot_blend,
                              inverse_basis=np.linalg.inv(m[:3, :3]) if abs(np.linalg.det(m[:3, :3])) > 1e-300
                              else None)
    elif data.type == "SUN":
        half = 0.5 * data.angle
        if not normalize and half > 0:  # radiance S instead of irradiance S
            power = power * math.pi * math.sin(half) ** 2
        light = SunLight(name, down, power, angle=data.angle)
    elif data.type == "AREA":
        size_v = data.size_y if data.shape in {"RECTANGLE", "ELLIPSE"} else data.size
        light = AreaLight(name, pos, m[:3, 0] * data.size, m[:3, 1] * size_v, down, power,
                          round=data.shape in {"DISK", "ELLIPSE"}, spread=getattr(data, "spread", math.pi))
        if not normalize:
            light.power = light.power * light.area
    else:
        warnings.append(f"light {name!r}: type {data.type} is not supported; skipped")
        return None
    light.visible = bool(getattr(obj, "visible_camera", False))  # Blender's lamps start unseen by the camera
    return light


def _broken_light(obj, matrix, light) -> str | None:
    """Why a light that the user meant to shine gives no light (None when it is fine or merely switched off)."""
    data = obj.data
    if not np.isfinite(_matrix(matrix)).all():
        return "its transform has non-finite values"
    if not (np.isfinite(data.color[:3]).all() and math.isfinite(data.energy)):
        return "its colour or power is not finite"
    if data.type == "AREA" and data.energy > 0 and not light.is_active:
        return "it has zero size"
    if data.energy > 0 and not light.is_active:
        return "its direction or size is not usable"
    return None


def _world(scene, warnings, progress=None) -> tuple[np.ndarray, Environment | None]:
    """(constant radiance, environment map or None) of the scene's world: a Background's constant colour or
    equirectangular Environment Texture read directly, any other tree as Cycles renders it (``world_bake``)."""
    world = scene.world
    if world is None:
        return np.zeros(3), None
    tree = world.node_tree
    if tree is None:
        return np.array(world.color[:3], np.float64), None
    outputs = [n for n in tree.nodes if n.type == "OUTPUT_WORLD"]
    active = [n for n in outputs if n.is_active_output] or outputs
    if not active or not active[0].inputs["Surface"].is_linked:
        return np.zeros(3), None
    node = active[0].inputs["Surface"].links[0].from_node
    if node.type != "BACKGROUND":
        return _baked(scene, world, warnings, progress)
    color, strength = node.inputs["Color"], node.inputs["Strength"]
    constant = np.array(color.default_value[:3], np.float64) * strength.default_value
    if strength.is_linked:
        return _baked(scene, world, warnings, progress)
    if not color.is_linked:
        return constant, None
    source = color.links[0].from_node
    if source.type != "TEX_ENVIRONMENT" or source.projection != "EQUIRECTANGULAR" or source.image is None:
        return _baked(scene, world, warnings, progress)
    rgb = image_pixels(source.image)
    if rgb is None:
        warnings.append(f"world {world.name!r}: Environment Texture {source.name!r} has image "
                        f"{source.image.name!r} that could not be loaded ({source.image.filepath or 'no file'}); "
                        f"using the constant colour")
        return constant, None
    rotation = _environment_rotation(world, source, warnings)
    environment = Environment.checked(rgb * strength.default_value, rotation)
    return (constant if environment is None else np.zeros(3)), environment


def _baked(scene, world, warnings, progress):
    """(no constant, the map Cycles bakes of ``world`` at the scene's frame) for ``_world``; a black world with a
    warning when Cycles cannot bake it."""
    try:
        image = baked_world(world, scene.frame_current, progress)
    except BakeError as err:
        warnings.append(f"world {world.name!r}: its node tree is read by letting Cycles render it, which failed "
                        f"({err}); the world is black")
        return np.zeros(3), None
    return np.zeros(3), Environment.checked(image)


def _environment_rotation(world, texture, warnings) -> np.ndarray:
    """The rotation taking a world direction to the Environment Texture's lookup direction: identity, or that of a
    Mapping node (Point, Vector or Texture type) on its Vector input."""
    vector = texture.inputs["Vector"]
    if not vector.is_linked:
        return np.eye(3)
    mapping = vector.links[0].from_node
    source = mapping.inputs["Vector"].links[0].from_socket.name if mapping.type == "MAPPING" and \
        mapping.inputs["Vector"].is_linked else None
    if source != "Generated" or mapping.vector_type not in {"POINT", "VECTOR", "TEXTURE"} or any(
            s.is_linked for s in mapping.inputs if s.name != "Vector"):
        warnings.append(f"world {world.name!r}: the Environment Texture's Vector comes from {mapping.bl_label!r}; "
                        f"only Texture Coordinate > Generated through a Mapping node is supported, so the map is "
                        f"not rotated")
        return np.eye(3)
    from mathutils import Euler
    rotation = _matrix(Euler(tuple(mapping.inputs["Rotation"].default_value), "XYZ").to_matrix())
    scale = np.array(mapping.inputs["Scale"].default_value)
    location = mapping.inputs.get("Location")  # a Vector-type Mapping has none
    if not np.allclose(scale, scale[0]) or (location is not None and np.any(np.array(location.default_value) != 0)):
        warnings.append(f"world {world.name!r}: Mapping {mapping.name!r}: only its rotation is used (location and "
                        f"non-uniform scale are not)")
    return rotation.T if mapping.vector_type == "TEXTURE" else rotation  # Texture maps by the inverse


def render_border(render, width: int, height: int) -> tuple[int, int, int, int] | None:
    """(x, y, width, height) of the pixels a render border keeps, y from the top, or None without one. Blender
    (``render_init_from_main``) scales the border's float32 corners by the frame's size and truncates them, y from
    the bottom; a border that spans the whole frame is no border."""
    if not render.use_border:
        return None
    corners = np.float32([render.border_min_x, render.border_max_x, render.border_min_y, render.border_max_y])
    if (corners == np.float32([0.0, 1.0, 0.0, 1.0])).all():
        return None
    x0, x1, y0, y1 = (int(c) for c in corners * np.float32([width, width, height, height]))
    if x1 <= x0 or y1 <= y0:
        raise ExtractionError(f"scene {render.id_data.name!r}: the render border (Output > Format > Render Region) "
                              f"is less than a pixel wide or high")
    return x0, height - y1, x1 - x0, y1 - y0


def camera_of(scene, depsgraph=None) -> Camera:
    """The camera of ``scene`` as ``depsgraph`` evaluates it (its animated transform and lens: in an animation
    render the original object stays where it was), or as stored without one."""
    cam_obj = scene.camera
    if cam_obj is None:
        raise ExtractionError(f"scene {scene.name!r} has no active camera (set Scene > Camera)")
    if depsgraph is not None:
        cam_obj = cam_obj.evaluated_get(depsgraph)
    cam = cam_obj.data
    if cam.type not in {"PERSP", "ORTHO"}:
        raise ExtractionError(f"camera {cam_obj.name!r}: type {cam.type} is not supported (use Perspective or "
                              f"Orthographic)")
    matrix = _matrix(cam_obj.matrix_world)
    if not np.isfinite(matrix).all():
        raise ExtractionError(f"camera {cam_obj.name!r}: its transform has non-finite values (location, rotation "
                              f"or scale)")
    r = scene.render
    width = max(1, int(r.resolution_x * r.resolution_percentage / 100))
    height = max(1, int(r.resolution_y * r.resolution_percentage / 100))
    window = view_window(width, height, orthographic=cam.type == "ORTHO", lens=cam.lens,
                         sensor_width=cam.sensor_width, sensor_height=cam.sensor_height, sensor_fit=cam.sensor_fit,
                         ortho_scale=cam.ortho_scale, shift_x=cam.shift_x, shift_y=cam.shift_y,
                         pixel_aspect=r.pixel_aspect_y / r.pixel_aspect_x)
    film = scene.vpl_gi  # the pixel filter: ours, the scene's Cycles filter until set (``properties``)
    return Camera(matrix, width, height, window, orthographic=cam.type == "ORTHO",
                  clip_start=cam.clip_start, clip_end=cam.clip_end, filter_type=film.pixel_filter_type,
                  filter_width=film.filter_width, region=render_border(r, width, height),
                  **depth_of_field(cam_obj, depsgraph))


def depth_of_field(cam_obj, depsgraph=None) -> dict:
    """``Camera``'s lens settings from the camera's Depth of Field panel, as Cycles reads them (``blender/camera.cpp``):
    an aperture of radius focal length / (2 f-stop) (1 / (2 f-stop) for an orthographic camera) and the focus
    distance, or with a Focus Object (and bone) the distance of its origin along the camera's view axis; nothing
    (a pinhole) with depth of field off or an f-stop that is not finite."""
    cam = cam_obj.data
    dof = cam.dof
    if not dof.use_dof or not math.isfinite(dof.aperture_fstop):
        return {}
    fstop = max(dof.aperture_fstop, 1e-5)
    focus = dof.focus_distance
    target = dof.focus_object
    if target is not None:
        if depsgraph is not None:
            target = target.evaluated_get(depsgraph)
        at = _matrix(target.matrix_world)
        bone = target.pose.bones.get(dof.focus_subtarget) if target.pose and dof.focus_subtarget else None
        if bone is not None:
            at = at @ _matrix(bone.matrix)
        matrix = _matrix(cam_obj.matrix_world)
        view = matrix[:3, 2] / max(np.linalg.norm(matrix[:3, 2]), 1e-300)
        focus = abs(float(np.dot(view, matrix[:3, 3] - at[:3, 3])))
    lens = {"aperture": (1.0 if cam.type == "ORTHO" else cam.lens * 1e-3) / (2.0 * fstop), "focus": focus,
            "blades": int(dof.aperture_blades), "blade_rotation": float(dof.aperture_rotation),
            "aperture_ratio": float(dof.aperture_ratio)}
    if not np.isfinite(list(lens.values())).all():
        raise ExtractionError(f"camera {cam_obj.name!r}: its Depth of Field has values that are not finite (focus "
                              f"{focus}, lens {cam.lens} mm, ratio {dof.aperture_ratio})")
    return lens


class _Objects:
    """The objects met, each once however often instanced: its index, Pass Index and asset (Cryptomatte's: the
    outermost parent, of the instancer for an instance, as in Cycles)."""

    def __init__(self):
        self.names: dict[str, int] = {}
        self.assets: dict[str, int] = {}
        self.pass_index: list[int] = []
        self.asset: list[int] = []

    def id_of(self, inst) -> int:
        obj = inst.object
        if obj.name not in self.names:
            top = inst.parent if inst.is_instance and inst.parent is not None else obj
            while top.parent is not None:
                top = top.parent
            self.names[obj.name] = len(self.names)
            self.pass_index.append(obj.pass_index)
            self.asset.append(self.assets.setdefault(top.name, len(self.assets)))
        return self.names[obj.name]


def extract(depsgraph, progress=None, camera: Camera | None = None,
            bake_uv: str | None = None) -> tuple[Scene, list[str]]:
    """The evaluated scene of ``depsgraph`` as engine arrays, and the warnings met on the way. ``progress(text)`` hears
    of long steps (Cycles baking the world) and may return False to stop them: ``Cancelled``. ``camera``: the view
    to render instead of the scene's camera (the viewport's). ``bake_uv``: the name of the UV map lightmaps are
    baked in (``ACTIVE_UV``: each mesh's render UV map), read into ``Scene.bake_uvs`` (zero where a mesh has
    none); None reads none."""
    scene = depsgraph.scene_eval
    warnings: list[str] = []
    camera = camera_of(depsgraph.scene, depsgraph) if camera is None else camera
    materials = MaterialTable(warnings)
    parts, lights, objects = [], [], _Objects()
    unsupported = Unsupported()
    unsupported.scene(depsgraph)
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.hide_render or unsupported.left_out(obj):  # a render depsgraph has dropped hidden objects already
            continue
        if obj.type == "LIGHT":
            light = _light(obj, inst.matrix_world, warnings)
            if light is not None:
                broken = _broken_light(obj, inst.matrix_world, light)
                if broken:
                    warnings.append(f"light {obj.name!r}: {broken}; it gives no light")
                lights.append(light)
        elif obj.type in GEOMETRY_TYPES:
            arrays = _mesh_arrays(obj, inst.matrix_world, materials, objects.id_of(inst), warnings, bake_uv)
            arrays = _without(arrays, unsupported.volume_faces(obj, materials))
            if arrays is not None:
                parts.append(arrays)
        else:
            continue  # empties, cameras...: nothing of theirs renders
        unsupported.instance(inst, materials)
    tangents = colors = baked = None
    if parts:
        triangles, normals, uvs, material, object_id = (np.concatenate(a) for a in list(zip(*parts))[:5])
        if any(p[5] is not None for p in parts):  # the rest are made from UVs by Scene.build
            tangents = np.concatenate([np.full((len(p[0]), 3, 4), np.nan) if p[5] is None else p[5]
                                       for p in parts])
        if any(p[6] is not None for p in parts):
            colors = np.concatenate([np.zeros((len(p[0]), 3, 3)) if p[6] is None else p[6] for p in parts])
        if bake_uv is not None:
            baked = np.concatenate([np.zeros((len(p[0]), 3, 2)) if p[7] is None else p[7] for p in parts])
    else:
        triangles = normals = np.zeros((0, 3, 3))
        uvs, material, object_id = np.zeros((0, 3, 2)), np.zeros(0, np.int32), np.zeros(0, np.int32)
    paths = depsgraph.scene.vpl_gi  # render settings: the original, not an evaluated copy
    bounces = min(paths.max_bounces, paths.diffuse_bounces)
    world, environment = _world(scene, warnings, progress)
    warnings += unsupported.warnings(materials)
    built = Scene.build(triangles, materials.build(), lights, camera, normals=normals, uvs=uvs, material=material,
                        object_id=object_id, object_names=list(objects.names) or ["none"], world=world,
                        environment=environment, textures=materials.textures, tangents=tangents, colors=colors,
                        max_bounces=bounces, object_pass_index=objects.pass_index or None,
                        object_asset=objects.asset or None, asset_names=list(objects.assets) or None,
                        bake_uvs=baked)
    return built, warnings
