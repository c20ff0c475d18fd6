"""The diffuse lobe under a normal map as Cycles (Blender 5) lights it: the bump shadowing term of
``materials.surface`` on direct light, on the gather's receivers, on camera-path vertices, and on the light a photon
leaves (``arrival_factor``)."""
import math

import numpy as np

from vpl_addon.core.sampling import normalize
from vpl_addon.materials.surface import Surface, arrival_factor, bump_factor, bump_shadowing, diffuse_cosine

UP = np.array([0.0, 0.0, 1.0])

# Cycles 5.0.1's Diffuse Direct of a white plane whose Normal Map node (constant colour) tilts the normal 30 degrees
# toward +x, lit by a sun of 1 W/m^2 from (sin a, 0, cos a): one deterministic sample per pixel, so exact to float
# precision (measured 2026-11-25 with Blender's bpy module, script in the issue 21 note)
CYCLES_TILT_30 = {0: 0.27566, 20: 0.31304, 40: 0.31121, 55: 0.28260, 65: 0.24932, 75: 0.19944, 82: 0.14183,
                  88: 0.04868}


def tilted(deg, k=1):
    t = math.radians(deg)
    return np.tile([math.sin(t), 0.0, math.cos(t)], (k, 1))


def test_diffuse_light_under_a_normal_map_is_what_cycles_renders():
    angles = np.radians(list(CYCLES_TILT_30))
    w = np.column_stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)])
    ns, smooth = tilted(30, len(w)), np.tile(UP, (len(w), 1))
    ours = diffuse_cosine(ns, smooth, w) / np.pi
    assert np.allclose(ours, list(CYCLES_TILT_30.values()), rtol=2e-4)
    plain = np.maximum((ns * w).sum(axis=1), 0.0) / np.pi  # without the term: 3.5x too bright at 88 degrees
    assert plain[-1] > 3.0 * CYCLES_TILT_30[88]


def test_no_normal_map_no_term():
    rng = np.random.default_rng(1)
    n = normalize(rng.normal(size=(100, 3)))
    w = normalize(rng.normal(size=(100, 3)))
    assert np.array_equal(bump_factor(n, n.copy(), w), np.ones(100))
    assert np.allclose(diffuse_cosine(n, n, w), np.maximum((n * w).sum(axis=1), 0.0), rtol=0.0, atol=1e-15)


def test_light_from_below_the_smooth_surface_is_cut_and_degenerate_directions_stay_finite():
    ns, smooth = tilted(40, 4), np.tile(UP, (4, 1))
    w = normalize(np.array([[1.0, 0.0, -0.2], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1e-9]]))
    g = bump_shadowing(smooth, ns, w)
    assert np.isfinite(g).all() and (g >= 0).all() and (g <= 1).all()
    assert g[0] == 0.0  # above the mapped normal's horizon but below the true surface: no light leaks through
    assert g[1] == 0.0 and g[3] == 0.0  # grazing the smooth surface
    assert g[2] == 1.0  # straight along the smooth normal


def surface(ns, smooth, incident):
    k = len(ns)
    zeros, ones = np.zeros((k, 3)), np.ones((k, 3))
    return Surface(position=zeros, geometric_normal=smooth, shading_normal=ns, prim=np.zeros(k, int),
                   material=np.zeros(k, int), albedo=ones, roughness=np.ones(k), metallic=np.zeros(k),
                   emission=zeros, specular=zeros, edge=zeros, dielectric=zeros, eta=np.ones(k),
                   incident=incident, smooth_normal=smooth)


def test_a_photon_brings_the_mapped_cosine_over_the_smooth_one_and_stays_bounded():
    rng = np.random.default_rng(2)
    k = 20000
    smooth = np.tile(UP, (k, 1))
    tilt = rng.uniform(0.0, 1.4, k)  # up to 80 degrees
    phi = rng.uniform(0.0, 2 * np.pi, k)
    ns = np.column_stack([np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi), np.cos(tilt)])
    w = normalize(rng.normal(size=(k, 3)))
    w[:, 2] = np.abs(w[:, 2])  # arriving from above
    f = arrival_factor(surface(ns, smooth, -w))
    assert np.isfinite(f).all() and (f >= 0).all() and f.max() <= 4.0 * math.sqrt(2.0)
    expected = diffuse_cosine(ns, smooth, w) / w[:, 2]
    assert np.allclose(f, expected)
    assert np.array_equal(arrival_factor(surface(smooth, smooth.copy(), -w)), np.ones(k))  # no map: as it was
