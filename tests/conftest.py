"""Shared fixtures. Engine tests import ``vpl_addon`` directly (no Blender); integration tests get the extension
package through ``ext`` (the repo root loaded as ``vpl_gi``, as ``python -m vpl_addon`` does) and the real bpy."""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "example_blends"
REFERENCES = ROOT / "tests" / "references"
EXAMPLE_SCENES = ("cornell_area", "cornell_point", "cornell_sun", "cornell_textured")


@pytest.fixture(scope="session")
def ext():
    from vpl_addon.__main__ import extension_package
    package = extension_package()
    import bpy  # noqa: F401  (fails loudly if the bpy module is missing)
    if not hasattr(bpy.types.Scene, "vpl_gi"):
        package.register()
    return package


@pytest.fixture
def small_blend(ext, tmp_path):
    """Save a tiny scene (a floor, optional camera/light/degenerate mesh) to a .blend and return a factory."""
    import bpy

    def make(camera=True, light=True, degenerate=False, name="s.blend"):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        scene.render.resolution_x = scene.render.resolution_y = 24
        mesh = bpy.data.meshes.new("Floor")
        mesh.from_pydata([(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], [], [(0, 1, 2, 3)])
        scene.collection.objects.link(bpy.data.objects.new("Floor", mesh))
        if degenerate:
            bad = bpy.data.meshes.new("Sliver")
            bad.from_pydata([(0, 0, 1), (1, 0, 1), (2, 0, 1)], [], [(0, 1, 2)])
            scene.collection.objects.link(bpy.data.objects.new("Sliver", bad))
        if camera:
            cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
            cam.location = (0, 0, 5)
            scene.collection.objects.link(cam)
            scene.camera = cam
        if light:
            lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
            lamp.location = (0, 0, 2)
            scene.collection.objects.link(lamp)
        path = tmp_path / name
        bpy.ops.wm.save_as_mainfile(filepath=str(path))
        return path

    return make


def run_cli(*args, cwd=ROOT, timeout=600):
    """``python -m vpl_addon ARGS`` in a fresh interpreter: (exit code, stdout, stderr)."""
    proc = subprocess.run([sys.executable, "-m", "vpl_addon", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout, env={**os.environ, "PYTHONPATH": str(ROOT)})
    return proc.returncode, proc.stdout, proc.stderr


def pass_errors(image, reference, name="Diffuse Direct") -> dict:
    """The ``compare`` CLI's errors of one pass of ``image`` against ``reference`` (rMAE, mean ratio, ...)."""
    code, stdout, stderr = run_cli("compare", image, reference, "--passes", name)
    assert code == 0, stderr
    return json.loads(stdout)[name]


def add_mesh(bpy, name, verts, faces, material=None, location=(0, 0, 0)):
    """A mesh object of ``verts`` and ``faces`` (with ``material``) linked into the current scene."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    if material is not None:
        mesh.materials.append(material)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def surface_material(bpy, name, build):
    """A material whose Surface is the output socket ``build(nodes, links)`` returns (its Principled BSDF removed)."""
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:  # Blender < 5.0
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.remove(nodes["Principled BSDF"])
    links.new(build(nodes, links), nodes["Material Output"].inputs["Surface"])
    return mat


def shader_material(bpy, name, shader, inputs):
    """A material of one ``shader`` node (its bl_idname) with ``inputs`` (socket name -> value) set."""
    def build(nodes, links):
        node = nodes.new(shader)
        for socket, value in inputs.items():
            node.inputs[socket].default_value = value
        return node.outputs[0]
    return surface_material(bpy, name, build)


def direct_against_cycles(label, blend, tmp_path, reference=None) -> tuple[dict, dict, str]:
    """Diffuse Direct of the engine (64 spp, no indirect) and of Cycles at 64 spp against ``reference`` (Cycles at
    1024 spp, rendered into ``tmp_path`` when not given): (our errors, Cycles' errors, the engine's stderr)."""
    ours, cycles = tmp_path / "ours.exr", tmp_path / "cycles64.exr"
    code, _, stderr = run_cli("render", blend, "-o", ours, "--samples", "64", "--method", "none")
    assert code == 0, stderr
    todo = [(cycles, 64)]
    if reference is None:
        reference = tmp_path / "reference.exr"
        todo.append((reference, 1024))
    for path, samples in todo:
        code, _, err = run_cli("reference", blend, "-o", path, "--samples", samples, "--cache-dir", tmp_path / "cache")
        assert code == 0, err
    e_ours, e_cycles = pass_errors(ours, reference), pass_errors(cycles, reference)
    print(f"{label}: ours rMAE {e_ours['rmae']:.4f} mean ratio {e_ours['mean_ratio']:.4f}; "
          f"Cycles 64 spp rMAE {e_cycles['rmae']:.4f} mean ratio {e_cycles['mean_ratio']:.4f}")
    return e_ours, e_cycles, stderr


def combined_against_cycles(blend, foil, tmp_path) -> tuple[dict, dict, dict]:
    """Combined of the engine (64 spp, no indirect) on ``blend`` and on ``foil`` (the scene without the feature
    under test, which must then score worse), and of Cycles at 64 spp on ``blend``, each against Cycles at 1024 spp
    on ``blend``: (our errors, the foil's, Cycles'). The engine's renders must give no warning."""
    ours, foiled, cycles, reference = (tmp_path / f"{n}.exr" for n in ("ours", "foil", "cycles64", "reference"))
    for path, scene in ((ours, blend), (foiled, foil)):
        code, _, stderr = run_cli("render", scene, "-o", path, "--samples", "64", "--method", "none")
        assert code == 0 and "warning" not in stderr.lower(), stderr
    for path, samples in ((cycles, 64), (reference, 1024)):
        code, _, stderr = run_cli("reference", blend, "-o", path, "--samples", samples, "--cache-dir",
                                  tmp_path / "cache")
        assert code == 0, stderr
    return tuple(pass_errors(p, reference, "Combined") for p in (ours, foiled, cycles))


def assert_direct_as_cycles(e_ours, e_cycles, stderr):
    """The judgement of ``direct_against_cycles``' figures for a scene the engine reads without a warning: Diffuse
    Direct mean within 2 % of the reference, rMAE within 1.5x Cycles' at equal samples (+ 0.01 for the edges)."""
    assert "warning" not in stderr.lower(), stderr
    assert abs(e_ours["mean_ratio"] - 1.0) <= 0.02
    assert e_ours["rmae"] <= 1.5 * e_cycles["rmae"] + 0.01


def add_sun(bpy, scene, rotation, energy=None, angle=None):
    """A sun lamp at Euler ``rotation`` linked into ``scene`` (energy and angle Blender's defaults when None)."""
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    if energy is not None:
        sun.data.energy = energy
    if angle is not None:
        sun.data.angle = angle
    sun.rotation_euler = rotation
    scene.collection.objects.link(sun)
    return sun


def camera_and_black_world(bpy, scene, location, rotation=(0.0, 0.0, 0.0)):
    """Give a scene built in a test its camera (at ``location``, Euler ``rotation``) and a black world."""
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = location, rotation
    scene.collection.objects.link(cam)
    scene.camera = cam
    world = bpy.data.worlds.new("Black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world


def plane_scene(lights=(), world=(0.0, 0.0, 0.0), size=10.0, height=5.0, res=32, view=2.0, materials=None,
                center=(0.0, 0.0, 0.0), scale=1.0):
    """A square floor (z = 0, facing +Z) seen straight down by an orthographic camera: pixel <-> position."""
    from vpl_addon.core.camera import Camera, view_window
    from vpl_addon.core.scene import Materials, Scene
    c = np.asarray(center, float)
    s = size * scale
    tri = np.array([[[-s, -s, 0], [s, -s, 0], [s, s, 0]], [[-s, -s, 0], [s, s, 0], [-s, s, 0]]], float) + c
    m = np.eye(4)
    m[:3, 3] = c + [0, 0, height * scale]
    cam = Camera(m, res, res, view_window(res, res, orthographic=True, ortho_scale=view * scale), orthographic=True,
                 clip_start=1e-3 * scale)
    return Scene.build(tri, materials or Materials.make([]), list(lights), cam, world=world)


def _stress_results() -> dict | None:
    """The stress suite's tally in this process (tests/stress/stress_scenes.py) with its methods, or None if it did
    not run here."""
    module = sys.modules.get("stress_scenes")
    if module is None or not module.RESULTS["renders"]:
        return None
    return {**module.RESULTS, "scenes": sorted(module.RESULTS["scenes"]), "methods": list(module.METHODS)}


_WORKERS_STRESS: list[dict] = []  # the tallies of pytest-xdist's workers, gathered by the controller


def pytest_sessionfinish(session):
    """On a pytest-xdist worker, hand the stress tally to the controller (``workeroutput`` goes back with the
    worker's end)."""
    results = _stress_results()
    if hasattr(session.config, "workeroutput") and results is not None:
        session.config.workeroutput["stress"] = results


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """On the controller, keep what a worker tallied of the stress suite."""
    stress = getattr(node, "workeroutput", {}).get("stress")
    if stress is not None:
        _WORKERS_STRESS.append(stress)


def pytest_terminal_summary(terminalreporter):
    """What the stress suite (tests/stress) covered, at the end of a run that included it, over all workers."""
    tallies = _WORKERS_STRESS + [r for r in [_stress_results()] if r is not None]
    if tallies:
        scenes = set().union(*(t["scenes"] for t in tallies))
        renders, bad = sum(t["renders"] for t in tallies), sum(t["bad_values"] for t in tallies)
        terminalreporter.write_line(f"stress suite: {len(scenes)} hostile scenes, {renders} renders over "
                                    f"methods {', '.join(tallies[0]['methods'])}: {bad} non-finite or negative values")
