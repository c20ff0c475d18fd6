"""One Blender version's round of the version matrix (``test_versions.py``), run by that version's ``bpy`` Python:
the zip installed into a throw-away user repository, the kernels compiled in the background, a small scene made here
(64 x 64, 4 samples: the same in every version) rendered twice with F12's operator, the extension disabled
and enabled again and rendered once more, then every committed example scene opened; the figures printed as one
JSON line.

Usage: python versions_render.py ZIP OUT_DIR (BLENDER_USER_EXTENSIONS, BLENDER_USER_CONFIG and VPL_GI_CACHE set).
"""
import json
import os
import sys
import threading
import time

import bpy

MODULE = "bl_ext.user_default.vpl_gi"
EXAMPLES = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                        "example_blends")


def timed(function, *args, **kwargs) -> float:
    t0 = time.perf_counter()
    function(*args, **kwargs)
    return time.perf_counter() - t0


def material(name, color):
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):  # nodes are always on from 5.0
        mat.use_nodes = True
    mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*color, 1.0)
    return mat


def plane(name, location, rotation, size, mat):
    mesh = bpy.data.meshes.new(name)
    h = size / 2
    mesh.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    obj.location, obj.rotation_euler = location, rotation
    bpy.context.scene.collection.objects.link(obj)


def make_scene(out_dir):
    """A floor, a red and a white wall and a box lit by an area light, seen by a camera: indirect light on the
    floor from the red wall."""
    scene = bpy.context.scene
    for obj in list(scene.collection.objects):
        bpy.data.objects.remove(obj)
    white, red = material("White", (0.8, 0.8, 0.8)), material("Red", (0.8, 0.1, 0.1))
    plane("Floor", (0, 0, 0), (0, 0, 0), 4, white)
    plane("Back", (0, 2, 2), (1.5708, 0, 0), 4, white)
    plane("Left", (-2, 0, 2), (0, 1.5708, 0), 4, red)
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0.5, 0.5, 0.5))
    light = bpy.data.objects.new("Area", bpy.data.lights.new("Area", "AREA"))
    light.data.energy, light.data.size, light.location = 200.0, 1.0, (0, 0, 3.9)
    scene.collection.objects.link(light)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location, camera.rotation_euler = (0, -7, 2), (1.5708, 0, 0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.render.engine = "VPL_GI"
    scene.render.resolution_x = scene.render.resolution_y = 64
    scene.render.resolution_percentage = 100
    scene.vpl_gi.samples, scene.vpl_gi.light_samples = 4, 1
    layer = scene.view_layers[0]
    for toggle in ("use_pass_diffuse_direct", "use_pass_diffuse_indirect", "use_pass_diffuse_color"):
        setattr(layer, toggle, True)
    if hasattr(scene.render.image_settings, "media_type"):  # 5.0 and newer
        scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
    scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    scene.render.use_file_extension = False
    return scene


def render(scene, path) -> float:
    scene.render.filepath = path
    return timed(bpy.ops.render.render, write_still=True)


def unopened_examples() -> list[str]:
    """The committed example scenes this Blender does not open with the add-on enabled, each with its error."""
    failed = []
    for name in sorted(os.listdir(EXAMPLES)):
        if name.endswith(".blend"):
            try:
                bpy.ops.wm.open_mainfile(filepath=os.path.join(EXAMPLES, name), load_ui=False)
            except RuntimeError as error:
                failed.append(f"{name}: {error}")
                continue
            if not hasattr(bpy.context.scene, "vpl_gi"):
                failed.append(f"{name}: opened without the add-on's settings")
    return failed


def main():
    zip_path, out_dir = sys.argv[1:3]
    figures = {"version": ".".join(map(str, bpy.app.version)), "python": sys.version.split()[0]}
    import numpy
    figures["numpy"] = numpy.__version__
    figures["install"] = timed(bpy.ops.extensions.package_install_files, filepath=zip_path, repo="user_default",
                               enable_on_install=True)
    engine = sys.modules[f"{MODULE}.operators.engine.render_engine"]
    kernels = sys.modules[f"{MODULE}.vpl_addon.precompile"].KERNELS
    figures["engine_file"] = engine.__file__
    figures["status_at_install"] = kernels.status()
    t0 = time.perf_counter()
    while not kernels.ready and kernels.error is None:  # the user opening a scene meanwhile
        time.sleep(0.5)
    figures["precompile"] = time.perf_counter() - t0
    figures["status"] = kernels.status()
    scene = make_scene(out_dir)
    figures["first_f12"] = render(scene, os.path.join(out_dir, "first.exr"))
    figures["reports"] = [list(r) for r in engine.LAST_REPORTS]
    figures["second_f12"] = render(scene, os.path.join(out_dir, "second.exr"))
    bpy.ops.preferences.addon_disable(module=MODULE)
    figures["threads_after_disable"] = [t.name for t in threading.enumerate() if t.name.startswith("vpl_gi")]
    figures["registered_after_disable"] = hasattr(bpy.types.Scene, "vpl_gi")
    bpy.ops.preferences.addon_enable(module=MODULE)
    scene.render.engine = "VPL_GI"
    figures["reenabled_f12"] = render(scene, os.path.join(out_dir, "reenabled.exr"))
    figures["reenabled_reports"] = [list(r) for r in sys.modules[f"{MODULE}.operators.engine.render_engine"]
                                    .LAST_REPORTS]
    figures["examples_unopened"] = unopened_examples()
    print("FIGURES " + json.dumps(figures), flush=True)
    if bpy.app.version < (4, 3, 0):  # the bpy 4.2 module crashes at interpreter exit once a panel was registered
        os._exit(0)


main()
