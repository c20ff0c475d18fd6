"""Which light a light sample at a shading point goes to, among many: a light tree (Conty Estevez and Kulla 2018,
"Importance Sampling of Many Lights with Adaptive Tree Splitting").

The lights with a position are the leaves of a binary tree. A node bounds its lights' positions (a sphere), the
directions they emit in (an orientation cone: axis, theta_o the spread of the lights' axes, theta_e the spread of
emission around each axis) and their total intensity. The importance of a node (their eq. 3) bounds the light its
lights can bring to a point x with normal n: intensity * cos(theta') * cos(theta'_i) / d^2, where d is the
distance to the node's centre (at least its radius), theta' is the angle between the cone's axis and the direction
to x less theta_o and the angle theta_u the bounding sphere subtends at x (zero past theta_e: no emitted light
reaches x), and theta'_i is the angle between n and the direction to the centre less theta_u (zero below the
horizon: a diffuse surface reflects nothing from there). For a point light (a leaf of radius 0) it is exactly the
light it brings, I cos(theta_i) / d^2, shadows aside; a planar light's leaf (an area light) gives nothing behind its
plane, where the sphere's bound would (cornell_textured's ceiling, lit only by an emitter beside the panel above it:
Diffuse Direct rMAE 0.160 with the sphere's bound, 0.047 with the plane, 0.073 choosing by power / d^2). The angles are
handled by their cosines and sines only.

A light sample first chooses among the nodes of a *cut* of the tree (``CUT`` nodes, every leaf when there are no
more lights than that), in proportion to their importance at its point, computed once per shading point for all
its samples (the cut of Walter et al.'s Lightcuts, 2005, fixed here rather than refined per point); below a node of
the cut it walks down to one light, at each node choosing a child in proportion to the child's importance (Conty
Estevez and Kulla, sec. 5.1), every sample of a batch taking one step per tree level. A light's probability is the
product of the choices on its path. On the stress suite's 200 point lights in a room, one light sample's relative
standard deviation (unshadowed, mean over the pixels) is 0.58 walking from the root, 0.21 below a cut of 64 nodes
and 0.011 choosing among every leaf, against 0.37 choosing by power / d^2 (no normal, 10 % uniform: the sampler
``bench/many_lights.py`` measures the tree against): the bounds of a node near x say little about which of its lights
is near, at a leaf the importance is exact.

With more lights than the cut holds, the tree is built top down, each node split where the surface area orientation
heuristic (sec. 4.4) is lowest, a node of a few lights in halves (with fewer, no sample walks the tree: halves).
Distant lights (the sun) have no position: each is a choice of its own beside the cut, its importance the
irradiance it can bring at the normal. A small share of the samples (``FLOOR``) picks a light uniformly, so that
no light that could matter is left with probability zero by a bound's rounding.
"""
from __future__ import annotations

import numpy as np

from ..core.sampling import dot

FLOOR = 0.01  # share of the light samples that choose a light uniformly
CUT = 256  # the most nodes the first choice is made among, at every point
CHUNK = 1 << 18  # pairs of point and node whose importance is computed at a time
BUCKETS = 12  # candidate split planes per axis when building
HEURISTIC_LEAST = 8  # a node of this many lights or fewer is split in halves, without the heuristic
ONE_BELOW = np.nextafter(1.0, 0.0)


def _cos_less(cos_a, sin_a, cos_b, sin_b):
    """cos(max(a - b, 0)) for angles a, b in [0, pi] given by their cosines and sines."""
    return np.where(cos_a >= cos_b, 1.0, cos_a * cos_b + sin_a * sin_b)


def _sin(cos):
    return np.sqrt(np.maximum(1.0 - cos * cos, 0.0))


def horizon_bound(cos_i, cos_u, sin_u):
    """cos(theta'_i), theta'_i = max(theta_i - theta_u, 0) (Conty Estevez and Kulla, eq. 3): the largest cosine
    between a normal and any direction within theta_u of one at cos_i to it, 0 below the horizon."""
    cos_i = np.clip(cos_i, -1.0, 1.0)
    return np.maximum(_cos_less(cos_i, _sin(cos_i), cos_u, sin_u), 0.0)


def _cone_measure(theta_o, theta_e):
    """M_Omega of an orientation cone (Conty Estevez and Kulla, sec. 4.4): the solid angle its emission covers,
    weighted by the cosine falloff past theta_o."""
    theta_w = np.minimum(theta_o + theta_e, np.pi)
    return 2.0 * np.pi * (1.0 - np.cos(theta_o)) + 0.5 * np.pi * (
        2.0 * theta_w * np.sin(theta_o) - np.cos(theta_o - 2.0 * theta_w) - 2.0 * theta_o * np.sin(theta_o)
        + np.cos(theta_o))


def _cones(member, axis, theta_o, theta_e):
    """Orientation cones bounding each row's members (``member`` (S, L) bool): axis the mean of the members' axes,
    theta_o the largest angle from it to a member's axis plus that member's theta_o (at most pi), theta_e the
    largest theta_e. Returns (axis (S,3), theta_o (S,), theta_e (S,))."""
    mean = member.astype(np.float64) @ axis
    length = np.linalg.norm(mean, axis=1, keepdims=True)
    mean = np.where(length > 1e-9, mean / np.where(length > 1e-9, length, 1.0), np.array([0.0, 0.0, 1.0]))
    off = np.arccos(np.clip(mean @ axis.T, -1.0, 1.0)) + theta_o
    spread = np.where(length[:, 0] > 1e-9, np.where(member, off, 0.0).max(axis=1), np.pi)
    return mean, np.minimum(spread, np.pi), np.where(member, theta_e, 0.0).max(axis=1)


class LightTree:
    """The light tree over a list of lights (``Light.bounds``, ``Light.orientation``, ``Light.intensity_estimate``;
    distant lights, ``Light.distant``, beside it): ``sample`` chooses one light per shading sample, ``probability``
    says how likely a given light was."""

    def __init__(self, lights, cut: int = CUT):
        self.count = len(lights)
        self.distant = np.array([i for i, light in enumerate(lights) if light.distant], np.int64)
        self.suns = [lights[i] for i in self.distant]
        placed = [i for i, light in enumerate(lights) if not light.distant]
        self.children, self.light = np.zeros((0, 2), np.int64), np.zeros(0, np.int64)
        self.cut, self.path = np.zeros(0, np.int64), np.full((len(lights), 1), -1, np.int64)
        # each light's first choice (its node of the cut, or its own place after them) and the depth it is at
        self.entry, self.below = np.zeros(len(lights), np.int64), np.zeros(len(lights), np.int64)
        self.entry[self.distant] = np.arange(len(self.distant))
        self.table, self.oriented, self.origin, self.points = np.zeros((0, 12)), False, np.zeros(3), False
        self.cut_rows, self.unit, self.scale = np.zeros((0, 12), np.float32), 1.0, 1.0
        if not placed:
            return
        self._tabulate(_nodes(_leaf_bounds([lights[i] for i in placed]), placed, cut))
        self.path = _paths(self.children, self.light, len(lights))
        self.cut = self._cut(cut)
        self.points = bool((self.table[self.cut, 3] == 0.0).all() and (self.table[self.cut, 8] <= -1.0).all())
        self.cut_rows, self.unit, self.scale = _cut_rows(self.table, self.cut, self.origin)
        self._entries(placed)

    def _tabulate(self, nodes):
        """The nodes (``_nodes``) as arrays: per node its ``children`` and ``light``, and its ``table`` row, gathered
        at once: centre, radius^2, intensity, axis, cos and sin theta_o, cos theta_e, 1 at the leaf of a light that
        emits from a plane through its centre to one side (``Light.planar``)."""
        center, radius, axis, spread, emit, intensity, plane, self.children, self.light = map(np.array, zip(*nodes))
        self.table = np.column_stack([center, radius ** 2, intensity, axis, np.cos(spread), np.sin(spread),
                                      np.cos(emit), plane])
        self.oriented = bool((spread < np.pi).any())  # else every node emits everywhere: no cone to test
        self.origin = center[0]

    def _entries(self, placed):
        """Each placed light's first choice (``entry``: the node of the cut above it) and the depth of that node on
        its path (``below``); the distant lights' choices after the cut's."""
        in_cut = np.full(len(self.children), -1)
        in_cut[self.cut] = np.arange(len(self.cut))
        on_path = np.where(self.path >= 0, in_cut[self.path], -1)[placed]
        self.below[placed] = np.argmax(on_path >= 0, axis=1)
        self.entry[placed] = on_path[np.arange(len(placed)), self.below[placed]]
        self.entry[self.distant] += len(self.cut)

    def _cut(self, size):
        """A cut of the tree: at most ``size`` nodes that together hold every light once, made by splitting the
        largest node first, starting from the root (all leaves if there are at most ``size`` lights)."""
        cut = [0]
        while len(cut) < size:
            inner = [k for k in cut if self.children[k, 0] >= 0]
            if not inner:
                break
            largest = max(inner, key=lambda k: self.table[k, 3])
            cut.remove(largest)
            cut += list(self.children[largest])
        return np.array(sorted(cut), np.int64)

    def importance(self, rows, p, n):
        """Importance of the nodes whose ``table`` rows are ``rows`` (..., 12) at points p with normals n (..., 3),
        broadcast against each other."""
        to = p - rows[..., 0:3]  # from the centre toward p
        return self._importance(rows, dot(to, to), -dot(n, to), dot(rows[..., 5:8], to))

    def _importance(self, rows, d2, toward, along):
        """Conty Estevez and Kulla's eq. 3 from the squared distance d2 between point and node centre, the normal's
        component toward the centre (``toward``) and the cone axis' component toward the point (``along``)."""
        r2 = rows[..., 3]
        inside = d2 <= r2
        d2 = np.maximum(d2, 1e-30)
        inv_d = 1.0 / np.sqrt(d2)
        sin2_u = np.where(inside, 1.0, r2 / d2)  # theta_u: the half angle the sphere subtends at p
        sin_u, cos_u = np.sqrt(sin2_u), np.sqrt(1.0 - sin2_u)
        value = rows[..., 4] * np.where(inside, 1.0, horizon_bound(toward * inv_d, cos_u, sin_u))
        if self.oriented:
            cos_t = np.clip(along * inv_d, -1.0, 1.0)  # between the cone's axis and the direction to p
            cos_o, sin_o = rows[..., 8], rows[..., 9]
            cos_a, sin_a = cos_o * cos_u - sin_o * sin_u, sin_o * cos_u + cos_o * sin_u  # theta_o + theta_u
            emit = np.where(sin_a < 0.0, 1.0, _cos_less(cos_t, _sin(cos_t), cos_a, sin_a))  # past pi: all
            value = value * np.where(inside | (emit >= rows[..., 10]), emit, 0.0)
            # a planar light's leaf: nothing behind its plane, which its sphere's cone bound would let through
            # (with that bound a ceiling above a downward panel sends its samples to the panel, and only the rest to
            # an emitter beside it)
            value = value * ((rows[..., 11] == 0.0) | (along > 0.0))
        return value / np.maximum(d2, r2)

    def _first_choice(self, p, n):
        """(P, E) the probability of each first choice at points p, normals n (P,3): the cut's nodes, then the
        distant lights, in proportion to their importance (evenly where all are zero). Computed in single
        precision, in units of the root's radius about its centre (``cut_rows``), the points no nearer a node's
        centre than a millionth of it; every pair of point and node on its own, so that ``sample`` and
        ``probability`` get the same numbers for a point."""
        value = np.empty((len(p), len(self.cut) + len(self.suns)))
        rows = self.cut_rows
        q, c, axis = ((p - self.origin) * self.unit).astype(np.float32), rows[:, 0:3], rows[:, 5:8]
        n = n.astype(np.float32)
        to = [q[:, k, None] - c[:, k] for k in range(3)]  # (P, C) each: from every node's centre to every point
        d2 = np.maximum(to[0] * to[0] + to[1] * to[1] + to[2] * to[2], np.float32(1e-12))
        toward = -(n[:, 0, None] * to[0] + n[:, 1, None] * to[1] + n[:, 2, None] * to[2])
        if self.points:  # every node of the cut a point light: eq. 3 is I max(cos, 0) / d^2
            value[:, :len(self.cut)] = rows[:, 4] * np.maximum(toward, 0.0) / (d2 * np.sqrt(d2))
        else:
            along = axis[:, 0] * to[0] + axis[:, 1] * to[1] + axis[:, 2] * to[2]
            value[:, :len(self.cut)] = self._importance(rows, d2, toward, along)
        for j, sun in enumerate(self.suns):
            value[:, len(self.cut) + j] = sun.irradiance_bound(n) * self.scale
        total = value.sum(axis=1, keepdims=True)
        return np.where(total > 0.0, value / np.where(total > 0.0, total, 1.0), 1.0 / value.shape[1])

    def _left_share(self, pair, p, n):
        """(K,) the probability of the left child of nodes with children ``pair`` (K,2) at points p, normals n: in
        proportion to the two children's importance, 1/2 where both are 0."""
        left, right = self.importance(self.table[pair[:, 0]], p, n), self.importance(self.table[pair[:, 1]], p, n)
        total = left + right
        return np.where(total > 0.0, left / np.where(total > 0.0, total, 1.0), 0.5)

    def sample(self, p, n, owner, u):
        """One light per sample from uniform numbers u (K,), sample i at point ``owner[i]`` of p, n (P,3): (the
        light's index in the list, the probability it had). The first choice is made per point (``CHUNK`` pairs of
        point and choice at a time), the walk below it per sample."""
        u = np.minimum(np.asarray(u, np.float64), ONE_BELOW)
        which, prob = np.empty(len(owner), np.int64), np.empty(len(owner))
        spread = np.nonzero(u < FLOOR)[0]  # the uniform share
        which[spread] = np.minimum((u[spread] / FLOOR * self.count).astype(np.int64), self.count - 1)
        rest = np.nonzero(u >= FLOOR)[0]
        u, at = np.minimum((u[rest] - FLOOR) / (1.0 - FLOOR), ONE_BELOW), owner[rest]
        first, chance = np.empty(len(rest), np.int64), np.empty(len(rest))
        width = len(self.cut) + len(self.suns)
        step = max(1, CHUNK // width)
        order = np.argsort(at, kind="stable")
        bounds = np.searchsorted(at[order], np.arange(0, len(p) + step, step))
        for c, lo in enumerate(range(0, len(p), step)):
            share = self._first_choice(p[lo:lo + step], n[lo:lo + step])
            s = order[bounds[c]:bounds[c + 1]]
            row = at[s] - lo
            cdf = np.cumsum(share, axis=1, dtype=np.float64)  # float64: the rows below are offsets up to CHUNK
            # every point's cdf shifted by its row: one sorted array for all samples of the chunk
            pick = np.searchsorted((cdf + np.arange(len(cdf))[:, None]).ravel(), row + u[s], side="right")
            last = width - 1 - np.argmax(share[:, ::-1] > 0.0, axis=1)  # past it only the cdf's rounding
            pick = np.clip(pick - row * width, 0, last[row])
            chance[s] = share[row, pick]
            below = np.where(pick > 0, cdf[row, np.maximum(pick - 1, 0)], 0.0)
            u[s] = np.clip((u[s] - below) / chance[s], 0.0, ONE_BELOW)
            first[s] = pick
        far = first >= len(self.cut)
        which[rest[far]] = self.distant[first[far] - len(self.cut)]
        # below the cut, one level per pass, the samples kept together while they walk
        down = np.nonzero(~far)[0]
        node, p_at, n_at, u_at, chance_at = self.cut[first[down]], p[at[down]], n[at[down]], u[down], chance[down]
        while len(down):
            inner = self.children[node, 0] >= 0
            if not inner.all():
                which[rest[down[~inner]]], chance[down[~inner]] = self.light[node[~inner]], chance_at[~inner]
                down, node, p_at, n_at, u_at, chance_at = (a[inner] for a in (down, node, p_at, n_at, u_at,
                                                                              chance_at))
                continue
            pair = self.children[node]
            left = self._left_share(pair, p_at, n_at)
            right = u_at >= left
            step = np.where(right, 1.0 - left, left)
            u_at = np.minimum((u_at - np.where(right, left, 0.0)) / step, ONE_BELOW)
            chance_at *= step
            node = pair[np.arange(len(pair)), right.astype(np.int64)]
        prob[rest] = (1.0 - FLOOR) * chance + FLOOR / self.count
        prob[spread] = self.probability(p[owner[spread]], n[owner[spread]], which[spread])
        return which, prob

    def probability(self, p, n, which):
        """(K,) the probability with which ``sample`` chooses light ``which`` (K,) at points p, normals n (K,3)."""
        chance = np.empty(len(p))
        step = max(1, CHUNK // (len(self.cut) + len(self.suns)))
        for lo in range(0, len(p), step):
            rows = np.arange(lo, min(lo + step, len(p)))
            chance[rows] = self._first_choice(p[rows], n[rows])[rows - lo, self.entry[which[rows]]]
        for depth in range(self.path.shape[1] - 1):  # the choices on each light's path below the cut
            node = self.path[which, depth + 1]
            rows = np.nonzero((node >= 0) & (depth >= self.below[which]))[0]
            node = node[rows]
            pair = self.children[self.path[which[rows], depth]]
            left = self._left_share(pair, p[rows], n[rows])
            chance[rows] *= np.where(node == pair[:, 1], 1.0 - left, left)
        return (1.0 - FLOOR) * chance + FLOOR / self.count


def _leaf_bounds(lights):
    """(centre (L,3), radius, axis (L,3), theta_o, theta_e, intensity, planar (L,)) of lights with a position: each
    one's bounding sphere (``Light.bounds``), orientation cone (``Light.orientation``), intensity estimate and 1 where
    it emits from a plane (``Light.planar``)."""
    center = np.array([light.bounds()[0] for light in lights], np.float64).reshape(-1, 3)
    radius = np.array([light.bounds()[1] for light in lights], np.float64)
    cones = [light.orientation() for light in lights]
    axis = np.array([c[0] for c in cones], np.float64).reshape(-1, 3)
    theta_o = np.array([c[1] for c in cones], np.float64)
    theta_e = np.array([c[2] for c in cones], np.float64)
    intensity = np.array([light.intensity_estimate() for light in lights], np.float64)
    planar = np.array([light.planar for light in lights], np.float64)
    return center, radius, axis, theta_o, theta_e, intensity, planar


def _nodes(leaves, placed, cut):
    """The tree's nodes over the lights ``placed`` (their indices in the list) of bounds ``leaves``
    (``_leaf_bounds``), the root first, built top down: per node its centre, radius, axis, theta_o, theta_e,
    intensity, planar, children ((-1, -1) at a leaf) and light (-1 inside). With more lights than ``cut`` a node of
    more than ``HEURISTIC_LEAST`` lights is split where the surface area orientation heuristic is lowest
    (``_split``), any other in halves."""
    center, bounds = leaves[0], leaves[:6]  # the inner nodes and the heuristic read all but planar
    nodes = [None]
    stack = [(np.arange(len(placed)), 0)]
    while stack:
        members, at = stack.pop()
        if len(members) == 1:  # a leaf keeps its light's own sphere
            i = members[0]
            nodes[at] = tuple(a[i] for a in leaves) + ((-1, -1), placed[i])
            continue
        children = (len(nodes), len(nodes) + 1)
        nodes += [None, None]
        nodes[at] = _inner_node(members, *bounds) + (children, -1)
        if len(placed) > cut and len(members) > HEURISTIC_LEAST:
            left = _split(members, *bounds)
        else:  # a few lights, or every leaf in the cut (no sample walks the tree then): halves
            left = _halves(center[members])
        stack += [(members[left], children[0]), (members[~left], children[1])]
    return nodes


def _inner_node(members, center, radius, axis, theta_o, theta_e, intensity):
    """(centre, radius, axis, theta_o, theta_e, intensity, planar) of an inner node over the lights ``members``: the
    sphere around their spheres' box, the cone bounding their cones (``_cones``), their total intensity; never
    planar."""
    lo = (center[members] - radius[members, None]).min(axis=0)
    hi = (center[members] + radius[members, None]).max(axis=0)
    cone = _cones(np.ones((1, len(members)), bool), axis[members], theta_o[members], theta_e[members])
    return (0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo), cone[0][0], cone[1][0], cone[2][0],
            intensity[members].sum(), 0.0)


def _paths(children, light, count):
    """(count, depth) the path from the root to each of ``count`` lights: its nodes by depth, -1 past its leaf
    (all -1 for a light without a leaf, a distant one), from the nodes' ``children`` and ``light``."""
    parent = np.full(len(children), -1)
    inner = np.nonzero(light < 0)[0]
    parent[children[inner, 0]], parent[children[inner, 1]] = inner, inner
    chains = {}
    for leaf in np.nonzero(light >= 0)[0]:
        chain = [leaf]
        while parent[chain[-1]] >= 0:
            chain.append(parent[chain[-1]])
        chains[light[leaf]] = chain[::-1]
    path = np.full((count, max(map(len, chains.values()))), -1, np.int64)
    for i, chain in chains.items():
        path[i, :len(chain)] = chain
    return path


def _cut_rows(table, cut, origin):
    """(the rows of the cut's nodes in single precision, the unit of length, the unit of intensity): lengths in units
    of the root's radius about ``origin`` (its centre), intensities in units of the largest (the distant lights'
    irradiance takes the same unit over the radius^2)."""
    unit = 1.0 / table[0, 3] ** 0.5 if table[0, 3] > 0.0 else 1.0
    rows = table[cut].copy()
    rows[:, 0:3] = (rows[:, 0:3] - origin) * unit
    rows[:, 3] *= unit ** 2
    scale = 1.0 / max(rows[:, 4].max(), 1e-300)
    rows[:, 4] *= scale * unit ** 2
    return rows.astype(np.float32), unit, scale


def _split(members, center, radius, axis, theta_o, theta_e, intensity):
    """(len(members),) bool: the lights of the left child, where the surface area orientation heuristic
    (Conty Estevez and Kulla, sec. 4.4) is lowest among ``BUCKETS`` planes across each axis of the centroids'
    box: intensity x box area x cone measure summed over the two sides, times the box's longest extent over its
    extent along the axis (their K_r, against thin boxes). Halves (``_halves``) where the lights share one centroid."""
    c = center[members]
    lo, hi = (c - radius[members, None]).min(axis=0), (c + radius[members, None]).max(axis=0)
    extent = hi - lo
    c_lo, c_hi = c.min(axis=0), c.max(axis=0)
    best, choice = np.inf, None
    for a in np.nonzero(c_hi > c_lo)[0]:
        bucket = np.minimum(((c[:, a] - c_lo[a]) / (c_hi[a] - c_lo[a]) * BUCKETS).astype(int), BUCKETS - 1)
        left = bucket[None, :] < np.arange(1, BUCKETS)[:, None]  # (splits, members)
        left = left[left.any(axis=1) & ~left.all(axis=1)]
        cost = sum(_side_cost(side, members, center, radius, axis, theta_o, theta_e, intensity)
                   for side in (left, ~left)) * extent.max() / max(extent[a], 1e-30)
        if len(cost) and cost.min() < best:
            best, choice = cost.min(), left[np.argmin(cost)]
    return _halves(c) if choice is None else choice


def _halves(c):
    """(len(c),) bool: the lights of the left child, the lower half of centroids c along their longest extent."""
    left = np.zeros(len(c), bool)
    left[np.argsort(c[:, np.argmax(c.max(axis=0) - c.min(axis=0))], kind="stable")[:len(c) // 2]] = True
    return left


def _side_cost(side, members, center, radius, axis, theta_o, theta_e, intensity):
    """(S,) intensity x box surface area x cone measure of each row's lights (``side`` (S, members) bool)."""
    c, r = center[members], radius[members, None]
    lo = np.where(side[:, :, None], (c - r)[None], np.inf).min(axis=1)
    hi = np.where(side[:, :, None], (c + r)[None], -np.inf).max(axis=1)
    e = hi - lo
    area = 2.0 * (e[:, 0] * e[:, 1] + e[:, 1] * e[:, 2] + e[:, 2] * e[:, 0])
    _, spread, emit = _cones(side, axis[members], theta_o[members], theta_e[members])
    return (side @ intensity[members]) * area * _cone_measure(spread, emit)
