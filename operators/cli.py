"""``python -m vpl_addon COMMAND``: render, reference and compare from the command line.

Every failure the user can cause (missing file, no camera, unwritable output, ...) ends as one line
``vpl_addon: error: ...`` on stderr and a non-zero exit status, never a traceback.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

from ..vpl_addon.core.denoise import PREFILTERS, QUALITIES
from ..vpl_addon.methods import METHODS, NONE, PATH_REUSE, MethodSettings
from ..vpl_addon.methods.base import exposed

EXIT_USAGE = 2
EXIT_FAILED = 1


PLACEMENT = exposed(MethodSettings)  # the placement settings users see, each a flag of render and bake


class UserError(Exception):
    """A problem with the input that the message explains."""


def _open_blend(path: str):
    import bpy
    if not os.path.isfile(path):
        raise UserError(f"no such file: {path}")
    try:
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path))
    except RuntimeError as err:
        raise UserError(f"cannot open {path}: {str(err).strip().splitlines()[-1]}") from None
    return bpy.context.scene


def _ensure_registered():
    import bpy
    if not hasattr(bpy.types.Scene, "vpl_gi"):
        from .. import register
        register()


def cmd_render(args) -> int:
    from . import engine
    from .output import check_target, render_to

    out = check_target(args.output, args.overwrite)
    if os.path.exists(out) and os.path.exists(args.scene) and os.path.samefile(out, args.scene):
        raise UserError(f"{out} is the scene being rendered; choose another output file")
    scene = _prepare_scene(args)
    if args.frame is not None:
        scene.frame_set(args.frame)
    t0 = time.perf_counter()
    render_to(scene, out, _verify)
    for level, message in engine.LAST_REPORTS:
        if level == "WARNING":
            print(f"warning: {message}", file=sys.stderr)
    stats = engine.LAST_STATS
    stages = ", ".join(f"{k} {v:.2f} s" for k, v in stats.get("seconds", {}).items())
    info = stats.get("info", {})
    method = stats.get("method")
    if method != "none" and "vpls" in info:
        method += f" {info['vpls']} VPLs"
        if "kept_reverse_share" in info:
            method += f" ({info['kept_reverse_share'] * 100:.0f} % reverse)"
        if "light_paths" in info:
            method += f", {info['light_paths']} light paths"
    print(f"wrote {out}: {stats.get('width')}x{stats.get('height')}, {stats.get('samples')} spp, {method}, "
          f"{time.perf_counter() - t0:.2f} s ({stages}), {stats.get('rays', 0) / 1e6:.1f} M rays")
    return 0


def _verify():
    """Called before an image replaces anything: the engine's first error, if any, ends the run."""
    from . import engine
    errors = [m for level, m in engine.LAST_REPORTS if level == "ERROR"]
    if errors:
        raise UserError(errors[0])


def parse_frames(text: str) -> range:
    """``A:B`` (inclusive, as Blender's -s/-e) or a single frame ``A``."""
    try:
        first, _, last = text.partition(":")
        first, last = int(first), int(last or first)
    except ValueError:
        raise UserError(f"--frames {text!r}: expected FIRST:LAST, e.g. 1:48") from None
    if last < first:
        raise UserError(f"--frames {text!r}: the last frame comes before the first")
    return range(first, last + 1)


def cmd_bake(args) -> int:
    from .bake import Bake, BakeError
    from .output import render_to
    frames = parse_frames(args.frames)
    if not os.path.isfile(args.scene):
        raise UserError(f"no such file: {args.scene}")
    if os.path.isfile(args.output):
        raise UserError(f"{args.output} is a file; -o takes the folder the frames go to")
    farm = args.scheduler is not None or args.workers is not None
    if args.scheduler is not None and args.workers is not None:
        raise UserError("--scheduler bakes on an existing Dask cluster, --workers on one it starts here: give one")
    for flag in ("workers", "chunk_size"):
        if getattr(args, flag) is not None and getattr(args, flag) < 1:
            raise UserError(f"--{flag.replace('_', '-')} must be at least 1")
    if args.chunk_size is not None and not farm:
        raise UserError("--chunk-size splits the range over --workers or a --scheduler's workers; a farm manager "
                        "runs each chunk as --frames A:B --sequence-start FIRST")
    if args.sequence_start is not None and (farm or args.sequence_start > frames.start):
        raise UserError(f"--sequence-start {args.sequence_start}: the frame a chunk's sequence starts at, at or "
                        f"before its first frame {frames.start}, and not with --workers or --scheduler (they chunk "
                        f"the range themselves)")
    scene = _prepare_scene(args)
    t0 = time.perf_counter()
    if farm:
        return _bake_on_cluster(args, scene, frames, t0)
    try:
        bake = Bake(scene, args.output, frames, args.overwrite, first=args.sequence_start)
    except BakeError as err:
        raise UserError(str(err)) from None

    printed = []

    def progress(fraction, text):
        entry = bake.report.frames[-1] if len(bake.report.frames) > len(printed) else None
        if entry is None:  # a step that rendered nothing: a cold start looking over the frames for what moves
            print(text, flush=True)
        else:
            printed.append(entry)
            traced = f" ({entry['light_path_rays']} rays)" if entry.get("light_path_rays") is not None else ""
            print(f"{text}: {entry['light_paths'] if entry['light_paths'] is not None else '-'} light paths{traced}"
                  f"{' (reused)' if entry['reused'] else ''}, {(entry['rays'] or 0) / 1e6:.2f} M rays, "
                  f"{entry['seconds']:.2f} s", flush=True)
        return True

    report = bake.run(progress, lambda path: render_to(scene, path, _verify))
    for warning in report.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    if report.skipped:
        print(f"skipped {len(report.skipped)} finished frames"
              + (f", resumed from the state after frame {report.resumed_from}" if report.resumed_from is not None
                 else ""))
    if report.replayed:
        print(f"placed the lights of frames {report.replayed[0]}:{report.replayed[-1]} to continue the sequence "
              f"from frame {bake.first}")
    print(f"baked {len(report.rendered)} frames to {os.path.abspath(args.output)} in "
          f"{time.perf_counter() - t0:.1f} s")
    return 0


def _bake_on_cluster(args, scene, frames, t0) -> int:
    """``bake`` in chunks on Dask workers (``operators/farm.py``): an existing scheduler's, or N processes here."""
    import importlib.util
    from . import farm
    from .bake import Bake, BakeError, frame_path
    if importlib.util.find_spec("distributed") is None:
        raise UserError("--workers and --scheduler need Dask: pip install 'dask[distributed]'")
    client = cluster = None
    bake = None
    try:
        if args.scheduler is not None:  # before anything is written: an unreachable scheduler leaves no trace
            client = farm.connect(args.scheduler)
        try:
            bake = Bake(scene, args.output, frames, args.overwrite)
        except BakeError as err:
            raise UserError(str(err)) from None
        done = [f for f in frames if os.path.exists(frame_path(bake.out_dir, f))]
        if len(done) == len(frames):  # nothing to do: no cluster started, no task sent
            print(f"skipped {len(done)} finished frames\nbaked 0 frames to {bake.out_dir}")
            return 0
        if client is None:
            client = farm.local_cluster(args.workers)
        workers = len(client.scheduler_info().get("workers", {}))
        size = args.chunk_size or farm.DEFAULT_CHUNK_SIZE
        print(f"baking frames {frames.start}:{frames.stop - 1} in chunks of {size} on "
              f"{args.scheduler or 'a local cluster'} ({workers} workers)", flush=True)
        from tqdm import tqdm
        with tqdm(total=len(frames), initial=len(done), unit="frame", desc="bake", file=sys.stderr,
                  dynamic_ncols=True) as bar:
            def progress(done):
                bar.update(done - bar.n)
            threads = None if args.workers is None else max(1, (os.cpu_count() or 1) // args.workers)
            report = farm.bake_on_cluster(client, bake, os.path.abspath(args.scene),
                                          {k: v for k, v in vars(args).items() if k != "run"}, size, progress, threads)
    except farm.FarmError as err:
        raise UserError(str(err)) from None
    finally:
        if bake is not None:
            bake.release()
        if client is not None:
            cluster = client.cluster
            client.close()
        if cluster is not None:
            cluster.close()
    for chunk in sorted(report.chunks, key=lambda c: c["frames"]):
        print(f"frames {chunk['frames'][0]}:{chunk['frames'][1]} on {chunk['host']} (pid {chunk['pid']}): "
              f"{len(chunk['rendered'])} rendered, {len(chunk['replayed'])} placed to continue the sequence, "
              f"{chunk['seconds']:.1f} s")
    if report.skipped:
        print(f"skipped {len(report.skipped)} finished frames")
    hosts = {(c["host"], c["pid"]) for c in report.chunks}
    print(f"baked {len(report.rendered)} frames to {bake.out_dir} in {time.perf_counter() - t0:.1f} s: "
          f"{len(report.chunks)} chunks on {len(hosts)} worker processes, {report.replayed} frames' lights placed "
          f"to continue the sequence across chunks")
    return 0


def _prepare_scene(args):
    """Open ``args.scene`` with the VPL GI engine, the settings given as flags and every pass on."""
    from . import engine
    from .extract import ExtractionError, camera_of
    _ensure_registered()
    scene = _open_blend(args.scene)
    try:
        camera_of(scene)
    except ExtractionError as err:
        raise UserError(str(err)) from None
    scene.render.engine = engine.VPLGIRenderEngine.bl_idname
    settings = scene.vpl_gi
    for flag in (*SETTING_FLAGS, *(setting.prop for setting in PLACEMENT)):
        if getattr(args, flag) is not None:
            _check_range(settings, flag, getattr(args, flag))
            setattr(settings, flag, getattr(args, flag))
    if args.no_filter:
        settings.filter = False
    settings.denoise = bool(getattr(args, "denoise", False))
    if getattr(args, "denoise_whole", False):
        settings.denoising_indirect_apart = False
    if args.percentage is not None:
        scene.render.resolution_percentage = args.percentage
    for layer in scene.view_layers:
        for _, toggle, _, _ in engine.LIGHT_PASSES:
            setattr(layer, toggle, True)
    return scene


def _check_range(settings, flag, value):
    """Blender clamps a number outside its property's range without a word (and keeps NaN): refuse it instead."""
    prop = settings.bl_rna.properties[flag]
    if not hasattr(prop, "hard_min"):
        return
    if not (math.isfinite(value) and prop.hard_min <= value <= prop.hard_max):
        bounds = f"between {prop.hard_min:g} and {prop.hard_max:g}" if prop.hard_max < 1e9 else \
            f"of at least {prop.hard_min:g}"
        raise UserError(f"--{flag.replace('_', '-')} {value:g}: must be a number {bounds}")


# the flags of the render settings that are not placement settings (those come from ``PLACEMENT``)
SETTING_FLAGS = ("samples", "light_samples", "seed", "method", "indirect_samples", "clamp", "interleave",
                 "denoising_prefilter", "denoising_quality")


def cmd_reference(args) -> int:
    from .output import check_target
    from .reference import SEED, TWIN_SEED, make_reference

    out = check_target(args.output, args.overwrite)
    if not os.path.isfile(args.scene):
        raise UserError(f"no such file: {args.scene}")
    _open_blend(args.scene)
    info = make_reference(args.scene, out, args.samples, args.frame, args.cache_dir, args.percentage,
                          TWIN_SEED if args.twin else SEED)
    how = "from cache" if info.get("cached") else f"{info['seconds']:.1f} s"
    print(f"wrote {out}: Cycles {args.samples} spp ({how}), hash {info['hash'][:12]}")
    return 0


def cmd_compare(args) -> int:
    from ..vpl_addon.evaluation.compare import compare_files, compare_sequences
    folders = [os.path.isdir(p) for p in (args.image, args.reference)]
    for path, folder in zip((args.image, args.reference), folders):
        if not (folder or os.path.isfile(path)):
            raise UserError(f"no such file: {path}")
    if folders[0] != folders[1]:
        raise UserError("compare two files, or two folders of frame_NNNN.exr (a sequence and its references)")
    names = [n.strip() for n in args.passes.split(",")] if args.passes else None
    try:
        if folders[0]:
            if args.heatmap:
                raise UserError("--heatmap is for single images, not sequences")
            result = compare_sequences(args.image, args.reference, names)
        else:
            result = compare_files(args.image, args.reference, names, args.heatmap)
    except ValueError as err:
        raise UserError(str(err)) from None
    print(json.dumps(result, indent=2))
    return 0


def cmd_bench(args) -> int:
    try:
        from ..bench.runner import Bench, BenchError, Options, all_methods, default_methods, parse_budgets
    except ModuleNotFoundError as err:
        if err.name != f"{__package__.rpartition('.')[0]}.bench":
            raise
        raise UserError("the benchmark runs from a clone of the repository: bench/ is not part of the installed "
                        "extension") from None
    methods = [m.strip() for m in args.methods.split(",") if m.strip()] if args.methods else list(default_methods())
    for m in methods:
        if m not in all_methods():
            raise UserError(f"--methods: unknown method {m!r}; choose from {', '.join(all_methods())}")
    if not methods:
        raise UserError("--methods: name at least one method")
    for scene in args.scenes:
        if not os.path.isfile(scene):
            raise UserError(f"no such file: {scene}")
    for flag in ("samples", "light_samples", "percentage", "gather_rays", "seeds"):
        value = getattr(args, flag)
        if value is not None and value < (0 if flag == "light_samples" else 1):
            raise UserError(f"--{flag.replace('_', '-')} must be at least {0 if flag == 'light_samples' else 1}")
    if args.time_cap is not None and args.time_cap <= 0:
        raise UserError("--time-cap must be positive")
    try:
        budgets = parse_budgets(args.budgets, methods)
    except BenchError as err:
        raise UserError(str(err)) from None
    out_dir = os.path.abspath(args.out)
    stems = [os.path.splitext(os.path.basename(s))[0] for s in args.scenes]
    targets = ["bench.csv", "summary.txt", *(f"{s}.png" for s in stems)] + (["scaling.csv"] if args.scaling else [])
    existing = [os.path.join(out_dir, t) for t in targets if os.path.exists(os.path.join(out_dir, t))]
    if existing and not args.overwrite:
        raise UserError(f"{existing[0]} exists; pass --overwrite to replace it (or choose another --out)")
    os.makedirs(out_dir, exist_ok=True)
    quick = args.quick
    options = Options(scenes=[os.path.abspath(s) for s in args.scenes], methods=methods, budgets=budgets,
                      out_dir=out_dir, percentage=args.percentage or (25 if quick else None),
                      samples=args.samples or (2 if quick else None),
                      light_samples=args.light_samples if args.light_samples is not None else (2 if quick else None),
                      denoise_prefilter=args.denoising_prefilter, denoise_quality=args.denoising_quality,
                      time_cap=args.time_cap if args.time_cap is not None else (10.0 if quick else 40.0),
                      reference_samples=args.reference_samples, cache_dir=args.cache_dir,
                      gather_rays=args.gather_rays or (200_000 if quick else 2_000_000), quick=quick,
                      scaling=args.scaling, seeds=args.seeds or 1)
    if args.reference_dir:
        options.reference_dir = os.path.abspath(args.reference_dir)
    _ensure_registered()
    try:
        summary = Bench(options, _open_blend).run()
    except BenchError as err:
        raise UserError(str(err)) from None
    with open(os.path.join(out_dir, "summary.txt"), "w") as f:
        f.write("\n".join(summary) + "\n")
    print("\n".join(summary))
    return 0


def cmd_scenes(args) -> int:
    from ..importers import shared_scenes
    from ..importers.mitsuba import MitsubaError
    if not os.path.isdir(args.source):
        raise UserError(f"no such folder: {args.source} (the public scenes, ../shared/scenes from the repository)")
    names = args.names or list(shared_scenes.SCENES)
    for name in names:
        if name not in shared_scenes.SCENES:
            raise UserError(f"unknown scene {name!r}; choose from {', '.join(shared_scenes.SCENES)}")
    for name in names:
        out = os.path.join(args.out, name + ".blend")
        t0 = time.perf_counter()
        try:
            written, warnings = shared_scenes.convert(args.source, name, out, width=args.width, force=args.force)
        except (MitsubaError, OSError) as err:
            raise UserError(str(err)) from None
        if not written:
            print(f"up to date: {out}")
            continue
        for w in warnings:
            print(f"  warning: {w}")
        print(f"wrote {out} ({os.path.getsize(out) / 1e6:.1f} MB, {time.perf_counter() - t0:.1f} s, "
              f"{len(warnings)} warnings)")
    return 0


def _placement_flag(r, setting) -> None:
    """The flag of one placement setting (``methods.base.Exposed``): ``--NAME VALUE``, or ``--no-NAME`` for a switch
    that is on by default; its help the setting's tooltip, said of the methods it applies to."""
    flag = setting.prop.replace("_", "-")
    owner = setting.path[0] if setting.path[0] in METHODS else None
    if owner is None and setting.prop in PATH_REUSE:
        owner = ", ".join(m.name for m in METHODS.values() if m.reuses_light_paths) + " in a sequence"
    how = setting.option
    text = (f"{owner}: " if owner else "") + how.description.replace("%", "%%") + \
        ("" if setting.kind is bool else f" (default {setting.default})")
    if setting.kind is bool:
        r.add_argument(f"--{'no-' if setting.default else ''}{flag}", dest=setting.prop, action="store_const",
                       const=not setting.default, help=text)
    elif how.items:
        r.add_argument(f"--{flag}", choices=[item[0] for item in how.items], help=text)
    else:
        r.add_argument(f"--{flag}", type=setting.kind, help=text)


def _render_flags(r) -> None:
    """The engine settings shared by ``render`` and ``bake``."""
    r.add_argument("--samples", type=int, help="camera samples per pixel")
    r.add_argument("--light-samples", type=int, help="shadow rays per camera sample for direct light")
    r.add_argument("--seed", type=int, help="random seed")
    r.add_argument("--method", choices=(*METHODS, NONE),
                   help="how virtual lights are placed (default: the scene's setting)")
    r.add_argument("--indirect-samples", type=int, help="camera samples per pixel that gather from the VPLs")
    r.add_argument("--clamp", type=float, help="geometry clamping: minimum distance in mean VPL spacings")
    r.add_argument("--interleave", type=int, help="interleaving tile size (1 = exact gather)")
    r.add_argument("--no-filter", action="store_true",
                   help="skip the geometry-aware filter of the indirect light (a denoised render skips it anyway)")
    r.add_argument("--denoise", action="store_true",
                   help="denoise Combined with OpenImageDenoise (F12's default; off here, so that Combined is the "
                        "estimate the benchmark judges unless asked)")
    r.add_argument("--denoising-prefilter", type=str.upper, choices=PREFILTERS,
                   help="with --denoise, as Cycles' Denoise > Prefilter: ACCURATE denoises the albedo and normal "
                        "guides first (three OIDN runs), FAST takes them as noisy and NONE as clean (one run each; "
                        "default: the scene's setting)")
    r.add_argument("--denoising-quality", type=str.upper, choices=QUALITIES,
                   help="with --denoise, OIDN's network as Cycles' Denoise > Quality (default: the scene's setting)")
    r.add_argument("--denoise-whole", action="store_true",
                   help="with --denoise, the whole image in one pass, as Cycles and a compositor Denoise node do it, "
                        "instead of the indirect light apart from the rest (the scene's Indirect Light Apart off)")
    for setting in PLACEMENT:
        _placement_flag(r, setting)
    r.add_argument("--percentage", type=int, help="resolution percentage (default: the scene's)")


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m vpl_addon",
                                description="VPL GI: indirect light with virtual lights, judged against Cycles.")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("render", help="render a .blend with the VPL GI engine to a multilayer EXR")
    r.add_argument("scene", help="the .blend file")
    r.add_argument("-o", "--output", required=True, help="multilayer EXR to write")
    r.add_argument("--frame", type=int, help="frame to render (default: the scene's current frame)")
    _render_flags(r)
    r.add_argument("--overwrite", action="store_true", help="replace OUTPUT if it exists")
    r.set_defaults(run=cmd_render)
    bk = sub.add_parser("bake", help="render a frame range to one multilayer EXR per frame, carrying each "
                                     "method's state from frame to frame (resumable)")
    bk.add_argument("scene", help="the .blend file")
    bk.add_argument("--frames", required=True, help="FIRST:LAST, inclusive (e.g. 1:48)")
    bk.add_argument("-o", "--output", required=True, help="folder for frame_NNNN.exr (and the bake's state)")
    _render_flags(bk)
    bk.add_argument("--overwrite", action="store_true",
                    help="replace a bake of other settings (or frames not from a bake) in the folder")
    bk.add_argument("--sequence-start", type=int, metavar="FRAME",
                    help="the range is a chunk of a sequence that starts at FRAME (a farm job's task): the method's "
                         "state is carried from there, so the chunks join without a seam")
    bk.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                    help="bake in chunks on the workers of this Dask scheduler (needs dask[distributed]; the .blend "
                         "and -o in folders every worker sees at the same path)")
    bk.add_argument("--workers", type=int, metavar="N", help="bake in chunks on N Dask worker processes on this "
                                                             "machine (needs dask[distributed])")
    bk.add_argument("--chunk-size", type=int, metavar="FRAMES",
                    help="frames per chunk with --workers or --scheduler (default 6)")
    bk.set_defaults(run=cmd_bake)
    ref = sub.add_parser("reference", help="render the Cycles reference of a .blend (cached by scene hash)")
    ref.add_argument("scene")
    ref.add_argument("-o", "--output", required=True)
    ref.add_argument("--samples", type=int, default=4096, help="Cycles samples per pixel (default 4096)")
    ref.add_argument("--frame", type=int)
    ref.add_argument("--percentage", type=int, help="resolution percentage (default: the scene's)")
    ref.add_argument("--twin", action="store_true",
                     help="render the reference's twin: Combined alone, with another seed, so its noise is "
                          "independent of the reference's; beside it in the bench's reference folder, the bench "
                          "takes the references' own noise out of its errors (clean_rrmse)")
    ref.add_argument("--cache-dir", default=os.path.join(os.path.expanduser("~"), ".cache", "vpl_gi"),
                     help="where converged references are kept by hash")
    ref.add_argument("--overwrite", action="store_true")
    ref.set_defaults(run=cmd_reference)
    c = sub.add_parser("compare", help="error of every common pass against a reference, as JSON; for two folders "
                                       "of frame_NNNN.exr, |E| and |E'| of the sequence (Hedman et al.)")
    c.add_argument("image", help="an EXR, or a folder of frames (a bake)")
    c.add_argument("reference", help="its reference, or a folder of per-frame references")
    c.add_argument("--heatmap", help="PNG of the per-pixel relative error")
    c.add_argument("--passes", help="comma-separated pass names (default: all in common)")
    c.set_defaults(run=cmd_compare)
    b = sub.add_parser("bench", help="time against error: every method and Cycles over their budgets, CSV + plots")
    b.add_argument("scenes", nargs="+", metavar="SCENE.blend")
    b.add_argument("--methods", help="comma-separated, from the engine's methods, each also as METHOD+oidn (its "
                                     "render denoised, judged on Combined), cycles and cycles+oidn (default: every "
                                     "engine method, the default one +oidn, cycles, cycles+oidn)")
    b.add_argument("--budgets", action="append", metavar="[METHOD=]N,N,...",
                   help="budgets of one method (VPL count; samples per pixel for cycles), or of every engine "
                        "method without METHOD=; repeatable")
    b.add_argument("--percentage", type=int, help="resolution percentage (default: the scene's; --quick: 25)")
    b.add_argument("--samples", type=int, help="engine camera samples per pixel (default: the scene's; --quick: 2); "
                   "vbnl's budget is its camera samples, so its runs take theirs from --budgets")
    b.add_argument("--light-samples", type=int, help="engine light samples (default: the scene's; --quick: 2)")
    b.add_argument("--denoising-prefilter", type=str.upper, choices=PREFILTERS,
                   help="the denoised engine runs' prefilter, as Cycles' (default: the scene's setting; Cycles + "
                        "OIDN keeps the scene's)")
    b.add_argument("--denoising-quality", type=str.upper, choices=QUALITIES,
                   help="the denoised engine runs' OIDN quality, as Cycles' (default: the scene's setting)")
    b.add_argument("--time-cap", type=float,
                   help="skip a method's larger budgets once its next run would take longer than this many seconds "
                        "(default 40; --quick: 10)")
    b.add_argument("--seeds", type=int,
                   help="run every budget with seeds 0..N-1; the curves take each budget's mean time and rMAE "
                        "(default 1)")
    b.add_argument("--scaling", action="store_true",
                   help="also time the first scene against triangle, pixel and VPL count (scaling.csv)")
    b.add_argument("--gather-rays", type=int, help="gather shadow rays replayed against raw embreex (default 2 M)")
    b.add_argument("--quick", action="store_true", help="a smoke run of seconds: 25 %% resolution, two budgets")
    b.add_argument("--out", default=os.path.join("out", "bench"), help="output folder (default out/bench)")
    b.add_argument("--reference-dir", help="committed references to use when their hash is fresh "
                                           "(default tests/references)")
    b.add_argument("--reference-samples", type=int, default=4096,
                   help="Cycles samples of a reference that must be rendered (default 4096)")
    b.add_argument("--cache-dir", default=os.path.join(os.path.expanduser("~"), ".cache", "vpl_gi"),
                   help="where rendered references are kept by hash")
    b.add_argument("--overwrite", action="store_true", help="replace the output files if they exist")
    b.set_defaults(run=cmd_bench)
    sc = sub.add_parser("scenes", help="convert the public scenes (Mitsuba XML, Cornell measured data, glTF) to .blend")
    sc.add_argument("names", nargs="*", help="scenes to convert (default: all)")
    sc.add_argument("--source", default=os.path.join("..", "shared", "scenes"),
                    help="folder of the public scenes (default ../shared/scenes)")
    sc.add_argument("--out", default="scenes", help="output folder (default scenes/, git-ignored)")
    sc.add_argument("--width", type=int, default=256, help="image width in pixels (default 256)")
    sc.add_argument("--force", action="store_true", help="rewrite files even if their fingerprint is current")
    sc.set_defaults(run=cmd_scenes)
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    try:
        return args.run(args)
    except UserError as err:
        print(f"vpl_addon: error: {err}", file=sys.stderr)
        return EXIT_USAGE
    except (FileExistsError, PermissionError, IsADirectoryError) as err:
        print(f"vpl_addon: error: {err}", file=sys.stderr)
        return EXIT_USAGE
    except Exception as err:  # the last line of defence: one line, never a traceback
        print(f"vpl_addon: error: {type(err).__name__}: {err}", file=sys.stderr)
        return EXIT_FAILED
