"""Where the default render's error floor is (issue 23): the denoised Combined of a scene at its own settings, and
the same image with its indirect light swapped for the converged reference's (and the reverse), so the share of the
error that the VPL indirect light carries is measured, not guessed; then that error averaged over k x k blocks (which
shrinks the reference's noise about k times and leaves bias) and, per 16 x 16 block, its sign and size.

    .venv/bin/python bench/indirect_floor.py [cornell_area] [--pairs 16,64,256] [--photons N,...] [--vpls N,...]
        [--no-filter]

The indirect light of a pass set is Diffuse Indirect x Diffuse Color (+ Glossy Indirect x Glossy Color where the
reference has them), Cycles' composition of Combined.
"""
from __future__ import annotations

import argparse
import dataclasses
import itertools

import numpy as np

from sample_counts import blend_path
from vbnl_stages import load_scene, register_extension
from vpl_addon.evaluation.metrics import block_means  # noqa: E402 (vbnl_stages puts the project on the path)


def _ints(text: str) -> list[int]:
    return [int(v) for v in text.split(",")]


def indirect(passes: dict) -> np.ndarray:
    """The indirect light in a pass set, as Cycles composes it into Combined."""
    total = 0.0
    for light, color in (("Diffuse Indirect", "Diffuse Color"), ("Glossy Indirect", "Glossy Color")):
        if light in passes and color in passes:
            total = total + passes[light][..., :3] * passes[color][..., :3]
    return total


def blocks(image: np.ndarray, k: int) -> np.ndarray:
    """(H/k, W/k) means of an (H,W,3) image's RGB over k x k blocks (the edge rows and columns left over dropped)."""
    return block_means(image[..., :3], k).mean(axis=-1)


def block_error(image: np.ndarray, reference: np.ndarray, k: int) -> float:
    """Mean absolute difference of the k x k block means over the mean of the reference."""
    ref = blocks(reference, k)
    return float(np.abs(blocks(image, k) - ref).mean() / ref.mean())


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene", nargs="?", default="cornell_area")
    p.add_argument("--pairs", type=_ints, default=[64],
                   help="vbnl's sample pairs per pixel, at the scene's camera samples")
    p.add_argument("--photons", type=_ints, default=[0], help="vbnl's photon paths (0: the scene's)")
    p.add_argument("--vpls", type=_ints, default=[0], help="the VPL budget (0: the scene's)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-filter", action="store_true", help="without the geometry-aware filter of the gather")
    args = p.parse_args(argv)
    blend = blend_path(args.scene)
    register_extension()
    import bpy
    from vpl_gi.bench.runner import ENGINE_PASSES, Options, engine_run, reference_for
    from vpl_gi.vpl_addon.core import passes as P
    from vpl_gi.vpl_addon.evaluation.metrics import coverage_mask, errors
    options = Options([], [], {}, "")
    bpy.ops.wm.open_mainfile(filepath=blend)
    reference, where = reference_for(blend, None, options.reference_dir, options.cache_dir, 4096, print)
    print(f"{args.scene}: reference {where}", flush=True)
    base = bpy.context.scene.vpl_gi.render_settings(ENGINE_PASSES)
    scene = load_scene(blend)
    ref = reference[P.COMBINED]
    mask = coverage_mask(ref[..., 3], ref.shape[:2])
    ref_indirect = indirect(reference)
    for pairs, photons, vpls in itertools.product(args.pairs, args.photons, args.vpls):
        placement = base.placement
        vbnl = placement.vbnl
        vbnl = dataclasses.replace(vbnl, photons=photons or vbnl.photons,
                                   sampling=dataclasses.replace(vbnl.sampling, samples=pairs))
        placement = dataclasses.replace(placement, vpls=vpls or placement.vpls, vbnl=vbnl)
        gather = dataclasses.replace(base.gather, filter=base.gather.filter and not args.no_filter)
        wall, result, _ = engine_run(scene, dataclasses.replace(base, seed=args.seed, placement=placement,
                                                                gather=gather))
        ours = result.passes[P.COMBINED][..., :3]
        our_indirect = indirect(result.passes)
        their_indirect_ours = ref[..., :3] - ref_indirect + our_indirect  # the reference, our indirect light

        def rmae(image):
            return errors(image, ref, mask)["rmae"]
        print(f"{pairs} pairs, {vbnl.photons} photons, {placement.vpls} VPLs, {wall:.1f} s: Combined {rmae(ours):.4f}; "
              f"with the reference's indirect light {rmae(ours - our_indirect + ref_indirect):.4f}; the reference "
              f"with ours {rmae(their_indirect_ours):.4f}; our indirect light's mean / the reference's "
              f"{our_indirect[mask].mean() / ref_indirect[mask].mean():.3f}", flush=True)
        print("  the reference with ours, block error (k: mean |difference| / mean): " + ", ".join(
            f"{k}: {block_error(their_indirect_ours, ref, k):.4f}" for k in (1, 4, 16)))
        signed = blocks(their_indirect_ours, 16) / np.maximum(blocks(ref, 16), 1e-12) - 1.0
        print("  per 16 x 16 block, % too bright (+) or dark (-), image top first:")
        for row in np.rint(100 * signed).astype(int):
            print("   " + " ".join(f"{v:3d}" for v in row))


if __name__ == "__main__":
    main()
