"""``python -m vpl_addon bench``: the command's flags and their checks, before ``runner`` runs the sweep. The command
line finds this module by name, as an optional part: the extension ships without ``bench/``."""
from __future__ import annotations

import os

from ..operators.cli.scene_flags import UserError, ensure_registered, open_blend
from ..vpl_addon.core.denoise import PREFILTERS, QUALITIES
from .runner import Bench, BenchError, Options, all_methods, default_methods, parse_budgets


def add_parser(sub) -> None:
    """The ``bench`` subcommand of the command line's parser."""
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
    b.set_defaults(run=run)


def run(args) -> int:
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
    ensure_registered()
    try:
        summary = Bench(options, open_blend).run()
    except BenchError as err:
        raise UserError(str(err)) from None
    with open(os.path.join(out_dir, "summary.txt"), "w") as f:
        f.write("\n".join(summary) + "\n")
    print("\n".join(summary))
    return 0
