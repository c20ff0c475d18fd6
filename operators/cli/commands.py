"""``python -m vpl_addon COMMAND``: render, bake, lightmap, reference and compare from the command line.

Every failure the user can cause (missing file, no camera, unwritable output, ...) ends as one line
``vpl_addon: error: ...`` on stderr and a non-zero exit status, never a traceback.
"""
from __future__ import annotations

import argparse
import importlib
import importlib.util
import json
import os
import sys
import time

from .scene_flags import UserError, open_blend, prepare_scene, render_flags, verify

EXIT_USAGE = 2
EXIT_FAILED = 1


def cmd_render(args) -> int:
    from ..engine import render_engine as engine
    from ..output.render_file import check_target, render_to

    out = check_target(args.output, args.overwrite)
    if os.path.exists(out) and os.path.exists(args.scene) and os.path.samefile(out, args.scene):
        raise UserError(f"{out} is the scene being rendered; choose another output file")
    scene = prepare_scene(args)
    if args.frame is not None:
        scene.frame_set(args.frame)
    _kernels_for(scene.vpl_gi.method)
    t0 = time.perf_counter()
    render_to(scene, out, verify)
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


def _kernels_for(method: str) -> None:
    """The kernels of ``method`` compiled (first use) or loaded from the cache before the render's clock starts,
    the time printed; the other methods' are left uncompiled, so the render has the cores."""
    from ...vpl_addon.precompile import KERNELS
    t0 = time.perf_counter()
    KERNELS.wait(method)
    KERNELS.stop()
    print(f"kernels of {method} ready in {time.perf_counter() - t0:.2f} s")


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
    from ..output.bake import Bake, BakeError
    from ..output.render_file import render_to
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
    scene = prepare_scene(args)
    if not farm:  # the workers compile their own
        _kernels_for(scene.vpl_gi.method)
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

    report = bake.run(progress, lambda path: render_to(scene, path, verify))
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
    """``bake`` in chunks on Dask workers (``operators/cli/farm.py``): an existing scheduler's, or N processes here."""
    import importlib.util
    from . import farm
    from ..output.bake import Bake, BakeError, frame_path
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


def cmd_reference(args) -> int:
    from ..output.render_file import check_target
    from ..output.reference import SEED, TWIN_SEED, make_reference

    out = check_target(args.output, args.overwrite)
    if not os.path.isfile(args.scene):
        raise UserError(f"no such file: {args.scene}")
    open_blend(args.scene)
    info = make_reference(args.scene, out, args.samples, args.frame, args.cache_dir, args.percentage,
                          TWIN_SEED if args.twin else SEED)
    how = "from cache" if info.get("cached") else f"{info['seconds']:.1f} s"
    print(f"wrote {out}: Cycles {args.samples} spp ({how}), hash {info['hash'][:12]}")
    return 0


def cmd_compare(args) -> int:
    from ...vpl_addon.evaluation.compare import compare_files, compare_sequences
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


def cmd_scenes(args) -> int:
    from ...importers import shared_scenes
    from ...importers.mitsuba import MitsubaError
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


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m vpl_addon",
                                description="VPL GI: indirect light with virtual lights, judged against Cycles.")
    sub = p.add_subparsers(dest="command", required=True)
    for add in (_render_parser, _bake_parser, _lightmap_parser, _reference_parser, _compare_parser, _bench_parser,
                _scenes_parser):
        add(sub)
    return p


def _render_parser(sub) -> None:
    """``render``: one frame to a multilayer EXR."""
    r = sub.add_parser("render", help="render a .blend with the VPL GI engine to a multilayer EXR")
    r.add_argument("scene", help="the .blend file")
    r.add_argument("-o", "--output", required=True, help="multilayer EXR to write")
    r.add_argument("--frame", type=int, help="frame to render (default: the scene's current frame)")
    render_flags(r)
    r.add_argument("--overwrite", action="store_true", help="replace OUTPUT if it exists")
    r.set_defaults(run=cmd_render)


def _bake_parser(sub) -> None:
    """``bake``: a frame range, here or on a Dask farm."""
    bk = sub.add_parser("bake", help="render a frame range to one multilayer EXR per frame, carrying each "
                                     "method's state from frame to frame (resumable)")
    bk.add_argument("scene", help="the .blend file")
    bk.add_argument("--frames", required=True, help="FIRST:LAST, inclusive (e.g. 1:48)")
    bk.add_argument("-o", "--output", required=True, help="folder for frame_NNNN.exr (and the bake's state)")
    render_flags(bk)
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


def _lightmap_parser(sub) -> None:
    """``lightmap``: each mesh's light baked into its UV map (``lightmap``)."""
    from .lightmap import add_parser
    add_parser(sub)


def _reference_parser(sub) -> None:
    """``reference``: a Cycles reference."""
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


def _compare_parser(sub) -> None:
    """``compare``: errors against a reference."""
    c = sub.add_parser("compare", help="error of every common pass against a reference, as JSON; for two folders "
                                       "of frame_NNNN.exr, |E| and |E'| of the sequence (Hedman et al.)")
    c.add_argument("image", help="an EXR, or a folder of frames (a bake)")
    c.add_argument("reference", help="its reference, or a folder of per-frame references")
    c.add_argument("--heatmap", help="PNG of the per-pixel relative error")
    c.add_argument("--passes", help="comma-separated pass names (default: all in common)")
    c.set_defaults(run=cmd_compare)


def _bench_parser(sub) -> None:
    """``bench``: from ``bench/command.py`` where the repository's bench/ is present."""
    bench = _optional_command("bench.command")
    if bench is None:
        b = sub.add_parser("bench", help="time against error (from a clone of the repository)")
        b.add_argument("rest", nargs=argparse.REMAINDER)
        b.set_defaults(run=_bench_missing)
    else:
        bench.add_parser(sub)


def _scenes_parser(sub) -> None:
    """``scenes``: the public scenes converted to .blend."""
    sc = sub.add_parser("scenes", help="convert the public scenes (Mitsuba XML, Cornell measured data, glTF) to .blend")
    sc.add_argument("names", nargs="*", help="scenes to convert (default: all)")
    sc.add_argument("--source", default=os.path.join("..", "shared", "scenes"),
                    help="folder of the public scenes (default ../shared/scenes)")
    sc.add_argument("--out", default="scenes", help="output folder (default scenes/, git-ignored)")
    sc.add_argument("--width", type=int, default=256, help="image width in pixels (default 256)")
    sc.add_argument("--force", action="store_true", help="rewrite files even if their fingerprint is current")
    sc.set_defaults(run=cmd_scenes)


def _optional_command(name: str):
    """The module of a command that lives in an optional part of the repository (``bench/``, which the extension
    does not ship), or None where that part is absent."""
    package = __package__.split(".")[0]
    if importlib.util.find_spec(f"{package}.{name.split('.')[0]}") is None:
        return None
    return importlib.import_module(f"{package}.{name}")


def _bench_missing(args) -> int:
    raise UserError("the benchmark runs from a clone of the repository: bench/ is not part of the installed "
                    "extension")


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
