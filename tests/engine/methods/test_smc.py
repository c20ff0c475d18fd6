"""Sequential Monte Carlo Instant Radiosity (Hedman et al.) and its parts, without Blender."""
import numpy as np
import pytest

from conftest import plane_scene
from test_sequence import lamp_scene
from vpl_addon.core.tracer import Tracer
from vpl_addon.lights import LightSet, PointLight
from vpl_addon.materials.surface import Surface
from vpl_addon.methods import MethodContext, MethodSettings, smc
from vpl_addon.methods.smc import SMCSettings, warmup_rounds
from vpl_addon.methods.smc.indirect_visibility import in_view, validate
from vpl_addon.methods.smc.knn_density import knn_density, rendering_k
from vpl_addon.methods.smc.vpl_radiosity import estimate_radiosity, vertex_numbers, vpl_numbers
from vpl_addon.sequence.motion import Motion, Snapshot


def test_knn_density_of_a_grid_and_the_k_of_eq_8():
    x, y = np.meshgrid(np.arange(40) * 0.1, np.arange(40) * 0.1)
    grid = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)
    inner = (np.abs(grid[:, :2] - 1.95) < 1.0).all(axis=1)
    p = knn_density(grid[inner], grid, 4, len(grid), exclude_self=True)
    area = 1.0 / (len(grid) * p)  # the area one point stands for: 0.01 on a 0.1 grid
    assert area == pytest.approx(np.full(inner.sum(), np.pi * 0.01 / 4))  # 4 neighbours at 0.1: pi r^2 / k
    assert rendering_k(2048) == 1 and rendering_k(4096) == 2 and rendering_k(16384) == 4 and rendering_k(0) == 1
    assert knn_density(grid[:1], grid[:1], 1, 1, exclude_self=True)[0] == 0.0  # nobody near: no density


def _points(scene, xy, z=0.0):
    n = len(xy)
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    return Surface(position=np.column_stack([xy, np.full(n, z)]), geometric_normal=up, shading_normal=up,
                   prim=np.zeros(n, np.int64), material=np.zeros(n, np.int32), albedo=np.full((n, 3), 0.5),
                   roughness=np.ones(n), metallic=np.zeros(n), emission=np.zeros((n, 3)), specular=np.zeros((n, 3)),
                   edge=np.zeros((n, 3)), dielectric=np.zeros((n, 3)), eta=np.ones(n), incident=-up)


def test_radiosity_with_one_vertex_is_the_direct_light_and_each_vpl_keeps_its_numbers():
    scene = plane_scene([PointLight("p", [0, 0, 2], [100.0] * 3)], size=5)
    tracer, lights = Tracer(scene.triangles), LightSet(scene)
    try:
        surface = _points(scene, np.array([[0.0, 0.0], [1.0, 0.5], [-2.0, 1.0]]))
        seeds = np.array([7, 8, 9])
        lo = estimate_radiosity(scene, tracer, lights, surface, seeds, 8, 1)
        d2 = (surface.position - [0, 0, 2]) ** 2
        cos = 2.0 / np.sqrt(d2.sum(axis=1))
        irradiance = 100.0 / (4 * np.pi) * cos / d2.sum(axis=1)
        assert lo[:, 0] == pytest.approx(0.5 / np.pi * irradiance, rel=1e-6)
        # a VPL's estimate does not depend on which other VPLs share the batch
        more = estimate_radiosity(scene, tracer, lights, surface.take([2, 0]), seeds[[2, 0]], 8, 3)
        again = estimate_radiosity(scene, tracer, lights, surface, seeds, 8, 3)
        np.testing.assert_array_equal(more, again[[2, 0]])
        assert not np.array_equal(vpl_numbers(np.array([1]), 2, 2), vpl_numbers(np.array([1]), 2, 2, seed=1))
    finally:
        tracer.close()


def _splitmix64(x):
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9 % 2**64
    x = (x ^ (x >> 27)) * 0x94D049BB133111EB % 2**64
    return x ^ (x >> 31)


def test_the_compiled_numbers_are_the_documented_hash_and_any_rows_can_be_asked_for():
    """A VPL's number j of vertex d of path s is SplitMix64(key + ((s V + d) 8 + j) c), key = SplitMix64(seed g +
    stream m + o), in Python integers; asking for some rows gives those rows of the full layout."""
    seeds, samples, vertices, stream = np.array([0, 7, 2**40 + 3]), 3, 4, 5
    full = vpl_numbers(seeds, samples, vertices, stream)
    for i, s, d, j in [(0, 0, 0, 0), (1, 2, 3, 7), (2, 1, 2, 4)]:
        key = _splitmix64((int(seeds[i]) * 0x9E3779B97F4A7C15 + stream * 0xC2B2AE3D27D4EB4F + 0x632BE59BD9B4E019)
                          % 2**64)
        bits = _splitmix64((key + ((s * vertices + d) * 8 + j) * 0xD1B54A32D192ED03) % 2**64)
        assert full[i, s, d, j] == (bits >> 11) / 2.0**53
    rows = vertex_numbers(seeds, np.array([2, 0, 2]), np.array([1, 2, 0]), 3, vertices, stream)
    np.testing.assert_array_equal(rows, full[[2, 0, 2], [1, 2, 0], 3])


def test_mailbox_validation_keeps_seen_vpls_and_finds_others_through_visible_points():
    scene = lamp_scene()  # floor z = 0 and a wall at y = 1; an orthographic camera looks down at the floor
    tracer = Tracer(scene.triangles)
    try:
        wall_normal = np.array([[0.0, -1.0, 0.0]] * 3)
        vpls = np.array([[0.0, 1.0, 0.5], [0.3, 1.0, 0.5], [0.0, 1.0, 2.0]])  # on the wall, facing the floor
        floor_up = np.array([[0.0, 0.0, 1.0]] * 3)
        box = np.array([[0.0, 0.0, 0.0], [9.0, 9.0, 9.0], [0.2, 0.2, 0.0]])  # the 2nd point is out of view
        assert in_view(scene.camera, box).tolist() == [True, False, True]
        points = np.array([[0.1, 0.1, 0.0], [-0.2, 0.3, 0.0]])
        valid, box_p, _ = validate(scene.camera, tracer, vpls, wall_normal, box, floor_up, points, floor_up[:2],
                                   np.random.default_rng(0), rays_per_point=16, iterations=2)
        assert valid.all()
        assert np.array_equal(box_p[0], box[0]) and not np.array_equal(box_p[1], box[1])  # found again
        behind = np.array([[0.0, 1.5, 0.5]])  # behind the wall: no visible point sees it
        valid, _, _ = validate(scene.camera, tracer, behind, wall_normal[:1], box[1:2], floor_up[:1], points,
                               floor_up[:2], np.random.default_rng(0))
        assert not valid.any()
    finally:
        tracer.close()


def _context(scene, tracer, seed=0):
    return MethodContext(scene, tracer, LightSet(scene), np.random.default_rng(seed), scene.max_bounces)


def test_at_most_m_max_vpls_move_per_frame_and_the_budget_is_kept():
    settings = MethodSettings(vpls=96, smc=SMCSettings(warmup=4, radiosity_samples=4, camera_points=256,
                                                       replacements=5))
    scene = lamp_scene()
    tracer = Tracer(scene.triangles)
    try:
        state = smc.start(None, settings)
        lights, info = smc.advance(state, _context(scene, tracer), settings, Motion(first=True))
        assert len(lights) == 96 and info["iterations"] == 5
        assert np.isfinite(lights.intensity).all() and (lights.intensity >= 0).all() and lights.intensity.max() > 0
        for step, light_at in enumerate([(0.2, 0.5, 1), (0.4, 0.5, 1), (0.6, 0.5, 1)], start=1):
            moved = lamp_scene(light_at=light_at)
            motion = Motion.between(Snapshot.of(scene), Snapshot.of(moved))
            before = state.seed.copy()
            lights, info = smc.advance(state, _context(moved, tracer, step), settings, motion)
            assert len(lights) == 96 and info["replaced"] <= 5 == settings.smc.replacements
            assert len(set(before.tolist()) - set(state.seed.tolist())) == info["replaced"]
            lives = np.isin(before, state.seed)  # a VPL that lives on keeps its slot; new ones take freed slots
            assert np.array_equal(state.seed[lives], before[lives]) and (~lives).sum() == info["replaced"]
            scene = moved
        still, info = smc.advance(state, _context(scene, tracer, 9), settings, Motion())
        assert info["reused"] and info["sampling_rays"] == 0 and np.array_equal(still.intensity, lights.intensity)
    finally:
        tracer.close()


def test_smc_lights_a_floor_off_a_wall_like_instant_radiosity():
    """The single-frame estimate (cold start with warm-up) agrees with ir on the light bounced off the wall, up to
    the bias of its areas (the hits at the wall's lower edge have no neighbours below: their kNN areas are too big)
    and of its VPLs' places (the replacements keep VPLs where their cells are brightest): 3-5 % too bright. Areas
    kept as a running mean of each round's cells, which leave out the VPLs that joined since, were 14-24 %."""
    from vpl_addon.gather.summing import GatherSettings
    from vpl_addon.render import RenderSettings, render
    scene = lamp_scene()
    common = dict(samples=4, light_samples=0, passes=("Combined", "Diffuse Indirect"),
                  gather=GatherSettings(interleave=1, clamp=0.0))
    ours = render(scene, RenderSettings(method="smc", placement=MethodSettings(
        vpls=512, smc=SMCSettings(warmup=10, camera_points=512)), **common)).passes["Diffuse Indirect"]
    ir = render(scene, RenderSettings(method="ir", placement=MethodSettings(vpls=8192), **common)
                ).passes["Diffuse Indirect"]
    assert np.isfinite(ours).all() and (ours >= 0).all()
    assert ours.mean() == pytest.approx(ir.mean(), rel=0.08)
    with pytest.raises(ValueError):
        SMCSettings(area="voronoi-ish")


def test_the_areas_are_the_remembered_hits_cells_among_the_vpls_as_they_are():
    """Each VPL's "voronoi" area is the area of the last ``area_frames`` rounds' hits nearest to it, averaged over
    the rounds; where an object moved, the frame's hits stand in for the earlier rounds' (whose hits lie where its
    surfaces were)."""
    settings = MethodSettings(vpls=64, smc=SMCSettings(warmup=6, warmup_rounds=6, radiosity_samples=4,
                                                       camera_points=256, area_frames=4))
    scene = lamp_scene()
    tracer = Tracer(scene.triangles)
    try:
        state = smc.start(None, settings)
        lights, _ = smc.advance(state, _context(scene, tracer), settings, Motion(first=True))
        assert len(state.hits) == 4  # of the 7 rounds, the last 4
        hits = np.concatenate([p for p, _ in state.hits])
        nearest = ((hits[:, None, :] - state.surface.position[None]) ** 2).sum(axis=2).argmin(axis=1)
        share = np.bincount(nearest, np.concatenate([a for _, a in state.hits]), minlength=64) / 4
        np.testing.assert_allclose(state.area, share, rtol=1e-5)
        np.testing.assert_allclose(lights.intensity, state.radiosity * share[:, None], rtol=1e-5)
        moved = lamp_scene(wall_shift=0.25)
        motion = Motion.between(Snapshot.of(scene), Snapshot.of(moved))
        smc.advance(state, _context(moved, tracer, 1), settings, motion)
        inside = [smc._inside_boxes(p, motion.boxes, 1e-6) for p, _ in state.hits]
        frame = state.hits[-1][0][inside[-1]]
        assert len(frame) and all(np.array_equal(p[m], frame) for (p, _), m in zip(state.hits, inside))
    finally:
        tracer.close()


def test_the_warm_up_shares_its_draws_of_candidates_in_rounds():
    """A cold start's first iteration fills the set; the warmup others and the frame's share ``warmup_rounds`` draws
    of candidates (as evenly as they go), one each at warmup_rounds >= warmup (the paper's cold start)."""
    assert warmup_rounds(SMCSettings()) == [1] + [7] * 4 + [6] * 12
    assert warmup_rounds(SMCSettings(warmup=10, warmup_rounds=4)) == [1, 3, 3, 2, 2]
    assert warmup_rounds(SMCSettings(warmup=4, warmup_rounds=99)) == [1, 1, 1, 1, 1]
    assert warmup_rounds(SMCSettings(warmup=1)) == [1, 1] and warmup_rounds(SMCSettings(warmup=0)) == [1]
    with pytest.raises(ValueError):
        SMCSettings(warmup_rounds=0)


def test_a_round_moves_at_most_m_max_vpls_an_iteration_and_ends_when_nothing_moves(monkeypatch):
    """Each iteration of a warm-up round replaces at most M_max VPLs, each from the round's candidates that no
    earlier iteration took; the round stops at the first iteration that moves nothing."""
    settings = MethodSettings(vpls=64, smc=SMCSettings(warmup=41, warmup_rounds=2, radiosity_samples=4,
                                                       camera_points=256, replacements=3))
    scene = lamp_scene()
    tracer = Tracer(scene.triangles)
    pools, rounds = [], []  # the pool of each round (kept alive), what each of its steps did
    original = smc._step

    def step(state, context, settings, pool, *args):
        before, offered = set(state.seed.tolist()), set(pool.seed.tolist())
        out = original(state, context, settings, pool, *args)
        new = set(state.seed.tolist()) - before
        assert new <= offered and not new & set(pool.seed.tolist())  # taken from the pool, and out of it
        if not pools or pools[-1] is not pool:
            pools.append(pool)
            rounds.append([])
        rounds[-1].append(None if out is None else len(new) if before else -1)
        return out
    monkeypatch.setattr(smc, "_step", step)
    try:
        state = smc.start(None, settings)
        lights, info = smc.advance(state, _context(scene, tracer), settings, Motion(first=True))
        assert len(lights) == 64 and info["iterations"] == 42 and len(set(state.seed.tolist())) == 64
        fill, *warm = rounds
        assert fill == [-1] and len(warm) == 2
        for moves in warm:
            assert 1 <= len(moves) <= 21 and all(0 < m <= 3 for m in moves[:-1])
        assert any(m is None for moves in warm for m in moves)  # a round that ended early
    finally:
        tracer.close()
