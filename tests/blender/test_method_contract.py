"""The method contract (``vpl_addon.methods.base``): a method is one folder plus one registry line. A copy of the
extension gains a toy sixth method, a constant ambient light, and nothing else is edited; the render panel's enum
and its drawn settings (through bpy), ``python -m vpl_addon render --help``, the bench's methods and a render from
the command line all find it."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from conftest import ROOT

AMBIENT = '''
"""A constant ambient light: every surface receives ``level`` from all around (the contract test's toy method)."""
from dataclasses import dataclass

import numpy as np

from ...gather.virtual_lights import STANDARD, VirtualLights
from ..base import Method, option


@dataclass
class AmbientSettings:
    level: float = option(0.25, label="Ambient Level", min=0.0, soft_max=10.0,
                          description="The radiance every surface receives from all around")


def place(context, settings):
    one = np.zeros((1, 3))
    return VirtualLights(one, one + [0.0, 0.0, 1.0], one, np.ones(1, np.int32), np.full(1, STANDARD, np.int8),
                         np.zeros(1, np.int64)), {"vpls": 1}


def gather(surface, lights, context, settings, rng, glossy=None, pixel=None):
    near = np.full((len(surface.position), 3), settings.ambient.level)
    return near, np.zeros_like(near)  # nothing comes over continued paths


METHOD = Method("ambient", "Ambient", "A constant ambient light", place, AmbientSettings, gather=gather,
                gather_samples=lambda settings, camera_samples: 1)
'''

IN_BLENDER = '''
import importlib, json, sys
sys.path.insert(0, sys.argv[1])
from vpl_addon.__main__ import extension_package
package = extension_package()
import bpy
package.register()
panels = importlib.import_module("vpl_gi.operators.ui.panels")
runner = importlib.import_module("vpl_gi.bench.runner")


class Layout:
    """Records the rows a panel's draw asks for (Blender's UILayout exists only inside a drawn region)."""
    def __init__(self, drawn):
        self.drawn, self.use_property_split, self.active = drawn, False, True

    def prop(self, data, name, **_):
        self.drawn.append(name)

    def __getattr__(self, name):  # column, row, label, operator...: what a draw lays out besides the settings
        return lambda *args, **kwargs: self


scene = bpy.context.scene
scene.vpl_gi.method = "ambient"
scene.vpl_gi.ambient_level = 0.75
drawn = []
panels.RENDER_PT_vpl_gi.draw(type("Panel", (), {"layout": Layout(drawn)})(), bpy.context)
print(json.dumps({
    "enum": [item.identifier for item in scene.vpl_gi.bl_rna.properties["method"].enum_items],
    "drawn": drawn,
    "level": scene.vpl_gi.render_settings(("Combined",)).placement.ambient.level,
    "bench": list(runner.all_methods()),
    "knob": runner.knob_of("ambient+oidn").name,
}))
'''


@pytest.fixture(scope="module")
def with_ambient(tmp_path_factory):
    """A copy of the extension with the toy method's folder and its one registry line."""
    copy = tmp_path_factory.mktemp("extension")
    for name in ("__init__.py", "blender_manifest.toml"):
        shutil.copy(ROOT / name, copy / name)
    for folder in ("vpl_addon", "operators", "importers", "bench"):
        shutil.copytree(ROOT / folder, copy / folder, ignore=shutil.ignore_patterns("__pycache__", "results"))
    (copy / "vpl_addon" / "methods" / "ambient").mkdir()
    (copy / "vpl_addon" / "methods" / "ambient" / "__init__.py").write_text(textwrap.dedent(AMBIENT))
    registry = copy / "vpl_addon" / "methods" / "__init__.py"
    text = registry.read_text()
    assert text.count('    "smc",\n') == 1
    registry.write_text(text.replace('    "smc",\n', '    "smc",\n    "ambient",\n'))
    return copy


def _run(copy, *args):
    proc = subprocess.run([sys.executable, *args], cwd=copy, capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PYTHONPATH": str(copy)})
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_a_sixth_method_reaches_the_panel_and_the_bench(with_ambient):
    found = json.loads(_run(with_ambient, "-c", IN_BLENDER, str(with_ambient)).splitlines()[-1])
    assert found["enum"] == ["vbnl", "bidir", "ir", "smc", "ambient", "none"]
    assert found["drawn"][found["drawn"].index("method") + 1:][:3] == ["vpls", "ambient_level", "filter"]
    assert "indirect_samples" not in found["drawn"]  # a method with its own gather shows none of the summing one's
    assert found["level"] == 0.75
    assert {"ambient", "ambient+oidn"} <= set(found["bench"]) and found["knob"] == "vpls"


def test_a_sixth_method_renders_from_the_command_line(with_ambient, small_blend, tmp_path):
    from vpl_addon.core.exr import read_passes
    usage = _run(with_ambient, "-m", "vpl_addon", "render", "--help")
    assert "ambient" in usage.split("--method")[1].split("}")[0] and "--ambient-level" in usage
    out = tmp_path / "ambient.exr"
    _run(with_ambient, "-m", "vpl_addon", "render", str(small_blend()), "-o", str(out), "--method", "ambient",
         "--ambient-level", "0.5", "--samples", "2", "--light-samples", "0")
    passes, _ = read_passes(str(out))
    assert np.allclose(passes["Diffuse Indirect"], 0.5, atol=1e-6)  # the floor fills the frame
