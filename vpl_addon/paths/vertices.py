"""Vertices of camera paths continued past their first hit, kept as arrays: the points, the shading point each one adds
its light to (``owner``), the path's throughput, and the lobe that reflects at them: the white Lambertian one (``lobe``
None; a diffuse colour is in the throughput) or a metallic one (``microfacet.GlossyLobe``, its weight and colour
inside). Used by the photon lights' renderer (``methods.vbnl.virtual_light_sampling``) and by the VPL gather's paths
over metal (``over_metal``)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.sampling import cosine_hemisphere, dot, group_sum
from ..lights.direct import direct_light
from ..materials.microfacet import GlossyLobe, glossy_color
from ..materials.surface import Surface, bump_factor

# next-event samples at a metallic vertex a camera path extends to: light reaching a diffuse point over metal
# (a caustic) comes only from them, and a sharp lobe catches a light rarely. Denoised, 4 give the error of 8 (3
# seeds, 64 samples: living room and veach_bidir the same to 0.0001, cornell_metal +0.3 %, cornell_pbr +0.4 %) in
# 6-11 % less time
GLOSSY_LIGHT_SAMPLES = 4
# at a rough coat's vertex (``Surface.rough_coat``), whose broad lobe catches lights as a diffuse one does: 8 samples
# there take 22 % of the hotel room's gather time
COAT_LIGHT_SAMPLES = 2


@dataclass
class PathVertices:
    point: Surface
    owner: np.ndarray  # (K,) the shading point each vertex adds to
    throughput: np.ndarray  # (K,3)
    lobe: GlossyLobe | None = None
    # (K,) which of its path's vertices at this depth each one is: 2b for the diffuse continuation of vertex b, 2b + 1
    # for the metallic one (a path branches at hits with both lobes); None: 0 for every vertex
    branch: np.ndarray | None = None

    @property
    def branches(self) -> np.ndarray:
        return np.zeros(len(self.owner), np.int64) if self.branch is None else self.branch

    def __len__(self):
        return len(self.owner)

    def evaluate(self, w, rows):
        """(f cos (R,3), pdf (R,)) toward ``w`` at vertices ``rows`` (the diffuse lobe's f cos with the bump
        shadowing term, ``surface.bump_factor``)."""
        if self.lobe is None:
            ns = self.point.shading_normal[rows]
            cos = np.maximum(dot(ns, w), 0.0) / np.pi
            return np.repeat((cos * bump_factor(ns, self.point.smooth_normal[rows], w))[:, None], 3, axis=1), cos
        return self.lobe.evaluate(w, rows)

    def sample(self, u):
        """(directions (K,3), f cos / pdf (K,3), pdf (K,)) of the lobe's own sampling with the uniform numbers
        ``u`` (2, K)."""
        if self.lobe is None:
            ns = self.point.shading_normal
            w, cos = cosine_hemisphere(u[0], u[1], ns)
            return w, np.repeat(bump_factor(ns, self.point.smooth_normal, w)[:, None], 3, axis=1), cos / np.pi
        return self.lobe.sample(u[0], u[1], np.arange(len(self.owner)))


def merged(vertices: list[PathVertices]) -> list[PathVertices]:
    """The vertices of one depth as at most two sets, the diffuse ones and the metallic ones: each set continues
    into both kinds, and kept apart the sets would double with every depth (54 small calls instead of 16 at 8
    bounces in the photon lights' renderer, each with the fixed cost of its k-d tree queries and ray batches)."""
    out = []
    for glossy in (False, True):
        part = [v for v in vertices if (v.lobe is not None) == glossy and len(v.owner)]
        if len(part) == 1:
            out.append(part[0])
        elif part:
            out.append(PathVertices(Surface.concat([v.point for v in part]), np.concatenate([v.owner for v in part]),
                                    np.concatenate([v.throughput for v in part]),
                                    GlossyLobe.concat([v.lobe for v in part]) if glossy else None,
                                    np.concatenate([v.branches for v in part])))
    return out


def roulette(weight: np.ndarray, rng: np.random.Generator,
             u: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Russian roulette (Arvo and Kirk 1990) on path vertices whose throughput with their own lobe's albedo is
    ``weight`` (K,3): (the rows that go on, 1/q for each of them), q = min(1, sqrt(max weight)), the probability
    with which Cycles continues a path (``path_state_continuation_probability``). Dividing the survivors'
    throughput by q keeps every estimate unbiased, while a path through a faint lobe (a clear coat's 4 %) stops
    early instead of branching on to the bounce limit. Only rows with 0 < q < 1 draw a number; q = 0 (or NaN)
    stops. ``u`` (K,): the rows' uniform numbers instead of the generator's."""
    q = np.minimum(np.sqrt(np.max(weight, axis=1, initial=0.0)), 1.0)
    live = q > 0.0
    doubt = np.nonzero(live & (q < 1.0))[0]
    live[doubt] = (rng.random(len(doubt)) if u is None else u[doubt]) < q[doubt]
    rows = np.nonzero(live)[0]
    return rows, 1.0 / q[rows]


def at_metal(y: Surface, rows: np.ndarray, owner: np.ndarray, throughput: np.ndarray, lights, tracer, rng,
             out: np.ndarray, branch: np.ndarray | None = None, unlit: np.ndarray | None = None) -> PathVertices:
    """The hits ``rows`` of ``y`` as metallic vertices (``owner``, ``throughput`` and ``branch`` given per hit,
    the branch of the vertex each hit came from; the new vertices are its metallic branches) that survive
    ``roulette`` on their throughput times their lobe's albedo (Glossy Color, ``microfacet.glossy_color``: the lobe
    is built for the survivors alone), their direct light through the lobe (next-event estimation,
    ``GLOSSY_LIGHT_SAMPLES`` with MIS, ``COAT_LIGHT_SAMPLES`` at a rough coat by light samples alone) added to
    ``out``, except at the ``unlit`` ones (per row of ``rows``: a caustic the caller takes from photons)."""
    live, boost = roulette(throughput[rows] * glossy_color(y, rows), rng)
    rows, lit = rows[live], np.ones(len(live), bool) if unlit is None else ~unlit[live]
    lobe = GlossyLobe.of(y, rows)  # for the few the roulette leaves
    metal = PathVertices(y.take(rows), owner[rows], throughput[rows] * boost[:, None], lobe,
                         None if branch is None else 2 * branch[rows] + 1)
    coat = metal.point.rough_coat
    for part, samples in ((np.nonzero(~coat & lit)[0], GLOSSY_LIGHT_SAMPLES),
                          (np.nonzero(coat & lit)[0], COAT_LIGHT_SAMPLES)):
        if len(part):
            light = direct_light(metal.point.take(part), lights, tracer, samples, rng, glossy=metal.lobe.take(part))[1]
            out += group_sum(metal.owner[part], metal.throughput[part] * light, len(out))
    return metal
