"""Light sources in Blender's units, their sampling toward a shading point (next-event estimation) and direct
light (``direct``): one module per kind of light, ``light_set.LightSet`` choosing among them. May import ``core``
and ``materials``.

Units follow Cycles (``scene/light.cpp``, ``kernel/light/*.h``), checked against Cycles' ``Diffuse Direct`` pass
by ``tests/cycles/test_cycles_direct.py``:

* point and spot, power P [W]: radiant intensity I = P / (4 pi) [W/sr]; with radius R the light is a sphere of
  radiance I / (pi R^2). A spot is a point light cut by a cone, not renormalised to it.
* area, power P [W] over area A: one-sided Lambertian emitter of radiance P / (pi A).
* sun, strength S [W/m^2]: irradiance S on a surface facing it, spread over a disc of the given angle.
* emissive triangles: radiance = Emission Color x Strength, emitted from both sides.
* world: constant radiance = Background Color x Strength from every direction (``world``), or an
  equirectangular Environment Texture times Strength, sampled by importance (``environment``).

``sample_incident(p, n, u1, u2, owner)`` returns, for light samples at shading points p with normals n (sample i at
point ``owner[i]``), unit directions toward the light, the distance to the sampled light point (inf for distant
lights), and L_e / pdf in solid angle: the estimator of the direct diffuse term is then
``le_over_pdf * max(0, n.wi) / pi * V``. A sample that cannot receive light (behind a one-sided area light) may
come back as a zero direction with zero weight. ``directions(p, n, u1, u2, owner)`` gives the same, but a light
whose weight costs more than a shadow ray (the environment map) hands its weight as a function of the rows, which
direct light asks only for the samples whose shadow ray got through.

``emit(count, rng, center, radius)`` starts light paths (Keller's Instant Radiosity): origins, unit directions and
the power each carries (emitted radiance over the joint pdf of position and direction, so the mean over paths is the
light's total power). Distant lights (sun, world) emit from a disc covering the scene's bounding sphere.
"""
from .area import AreaLight
from .emissive import EmissiveTriangles
from .environment import EnvironmentLight
from .light import Light
from .light_set import LightSet
from .point import PointLight, SpotLight
from .sun import SunLight
from .world import WorldLight

__all__ = ["AreaLight", "EmissiveTriangles", "EnvironmentLight", "Light", "LightSet", "PointLight", "SpotLight",
           "SunLight", "WorldLight"]
