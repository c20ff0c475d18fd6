"""The guard at the output (issue 8, item 3): a non-finite or negative value made by any stage fails the render
with a message naming the method, the stage and the pass; it is never zeroed away. Bad values are injected by a
method that places broken VPLs and by stages wrapped to spoil their own output."""
import dataclasses

import numpy as np
import pytest

import vpl_addon.render as render_module
from stress_scenes import room, small_settings
from vpl_addon.core.passes import BadOutput, check
from vpl_addon.methods import METHODS
from vpl_addon.render import render


def spoil(function, value):
    """``function`` whose result has ``value`` written into its first element."""
    def spoiled(*args, **kwargs):
        out = np.array(function(*args, **kwargs), dtype=np.float64)
        out.reshape(-1)[0] = value
        return out
    return spoiled


@pytest.mark.parametrize("value", [np.nan, np.inf, -1.0], ids=["nan", "inf", "negative"])
def test_a_method_placing_broken_vpls_is_named_with_stage_place(monkeypatch, value):
    """A method whose VPLs carry a NaN, infinite or negative intensity stops the render at stage 'place'."""
    def place(context, settings):
        vpls, info = METHODS["ir"].place(context, settings)
        vpls.intensity[0, 1] = value
        return vpls, info
    monkeypatch.setitem(METHODS, "broken", dataclasses.replace(METHODS["ir"], name="broken", place=place, start=None,
                                                               advance=None))
    with pytest.raises(BadOutput, match=r"method 'broken', stage 'place': VPL intensity: "):
        render(room(), small_settings("broken"))


@pytest.mark.parametrize("attribute, stage, name", [
    ("direct_light", "direct light", "Diffuse Direct"),
    ("gather", "gather", "Diffuse Indirect"),
    ("deinterleave", "filter", "Diffuse Indirect"),
])
@pytest.mark.parametrize("value", [np.nan, -1e-3], ids=["nan", "negative"])
def test_a_bad_value_names_method_stage_and_pass(monkeypatch, attribute, stage, name, value):
    """A stage that produces one bad value fails the render naming the method, that stage and the pass, with the
    count of bad values."""
    monkeypatch.setattr(render_module, attribute, spoil(getattr(render_module, attribute), value))
    kind = "1 non-finite, 0 negative" if np.isnan(value) else "0 non-finite, 1 negative"
    with pytest.raises(BadOutput, match=f"method 'ir', stage '{stage}': {name}: {kind} values"):
        render(room(), small_settings("ir"))


@pytest.mark.filterwarnings("ignore:overflow encountered in cast")
def test_values_too_large_for_the_pass_format_fail_at_the_output():
    """Light so bright that the float32 passes overflow (1e42 W): finite inside the engine, infinite in the passes,
    so the render fails at stage 'output' instead of writing infinities."""
    from vpl_addon.lights import PointLight
    scene = room(lights=[PointLight("nova", [0, 0, 1.8], [1e42] * 3)])
    with pytest.raises(BadOutput, match=r"method 'none', stage 'output': .*Combined: \d+ non-finite"):
        render(scene, small_settings("none"))


def test_check_counts_every_bad_value_and_passes_clean_arrays():
    """check() reports each array's own counts, and is silent on finite non-negative arrays."""
    check({"a": np.zeros((4, 4, 3)), "b": np.ones(3)}, "stage")
    with pytest.raises(BadOutput) as err:
        check({"a": np.array([np.nan, np.inf, -np.inf, -2.0, 1.0]), "b": np.zeros(2)}, "method 'x', stage 'y'")
    assert str(err.value) == "method 'x', stage 'y': a: 3 non-finite, 2 negative values"
