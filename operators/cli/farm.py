"""Baking a frame range on a Dask cluster in chunks, the way render farms split a shot.

The client (``python -m vpl_addon bake ... --scheduler tcp://HOST:PORT``, or ``--workers N`` for a cluster of N
processes on this machine) claims the range in the bake folder and records its settings (``bake.Bake``), then submits
one task per chunk of ``chunk_size`` frames that is not finished. A task runs ``render_chunk`` on a worker: the same
``Bake`` over its chunk, with ``first`` the range's first frame, so it continues the method's state from the nearest
state saved in the folder (or a cold start at ``first``) by placing the lights of the frames before it
(``bake.place_only``): the chunks write the bytes one bake in one process writes, without a seam where they meet.

Where things live, and why:

* The .blend and the bake folder are on storage every worker sees at the same path (as Flamenco and Deadline farms
  work): a scene's textures, linked libraries and caches sit beside it by relative path, which the .blend's bytes
  sent with each task would leave behind, and the frames go into one folder anyway. The task carries the file's
  SHA-256; a worker that cannot see the file, or sees another one, says so in one line.
* The extension: the task is a small function sent by value (``_on_worker``) that loads the worker's own copy
  (``vpl_addon.__main__.call``), so a worker whose Python lacks it says so in one line instead of failing to
  receive the task.
* Frames appear under their final names only when complete: a worker renders into ``.farm/<host>/`` in the folder
  and renames the finished file into place (``render_to`` writes a ``.partial-<pid>-`` file there first), so a worker
  killed mid-frame leaves a partial file there under no frame's name, and each host clears only its own dead
  processes' partial files.
* A worker lost mid-chunk (killed, out of memory, its machine gone) has its chunk run again elsewhere by Dask; that
  run skips the frames already in the folder and continues from the state the lost one saved last. A lost
  scheduler ends the client with one line; the same command run again renders only the frames that are missing.
* Progress counts the frames in the folder as they appear, whichever worker wrote them.
* One chunk at a time per worker process (bpy holds one scene per process): ``--workers N`` starts N processes of
  one thread; on a cluster of its own, chunks given to several threads of one worker take turns.
"""
from __future__ import annotations

import argparse
import hashlib
import importlib
import logging
import os
import pickle
import shutil
import socket
import sys
import threading
import time
from dataclasses import dataclass, field

# Frames per chunk (``--chunk-size``): 4 chunks of a 24-frame shot, 2 per worker of two; chunks of 4, 6 and 12 take
# the same time in bench/farm.py (ir, 2 workers), where the fixed costs of the cluster dominate.
DEFAULT_CHUNK_SIZE = 6
STAGING_DIR = ".farm"
CONNECT_SECONDS = 5


class FarmError(Exception):
    """A problem with the cluster, a worker or the input; the message is one line that explains it."""


def chunks(frames: range, size: int) -> list[range]:
    """``frames`` cut into consecutive ranges of ``size`` frames (the last may be shorter)."""
    return [range(start, min(start + size, frames.stop)) for start in range(frames.start, frames.stop, size)]


def sha256(path: str) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _quiet_client():
    """Dask's client logs a lost scheduler itself ("Failed to reconnect ... closing client"), at a moment that
    depends on timing; the CLI says it in its one line (``_result``), so the client's own log keeps quiet."""
    logging.getLogger("distributed.client").setLevel(logging.CRITICAL)


def connect(address: str):
    """A client of the Dask scheduler at ``address`` (FarmError if it cannot be reached)."""
    from distributed import Client
    _quiet_client()
    try:
        return Client(address, timeout=CONNECT_SECONDS, set_as_default=False)
    except (OSError, ValueError, TypeError) as err:
        reason = " ".join(str(err).split()) or type(err).__name__
        raise FarmError(f"cannot reach the Dask scheduler at {address} ({reason}); start one with `dask scheduler`, "
                        f"or bake on this machine with --workers N") from None


def local_cluster(workers: int):
    """A client of ``workers`` Dask worker processes of one thread on this machine (loopback only, no dashboard;
    no memory limit: a render's memory is not Dask's to spill, and a nanny's kill at a guessed limit loses work)."""
    from distributed import Client, LocalCluster
    _quiet_client()
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, memory_limit=0, silence_logs=logging.ERROR)
    return Client(cluster, set_as_default=False)


@dataclass
class FarmReport:
    rendered: list[int] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)  # frames finished before this run (no task for whole chunks)
    replayed: int = 0  # frames whose lights chunks placed to continue the state, without rendering them
    chunks: list[dict] = field(default_factory=list)  # per chunk run: frames, host, pid, seconds


def bake_on_cluster(client, bake, scene_path: str, flags: dict, chunk_size: int, progress=None,
                    threads: int | None = None) -> FarmReport:
    """Bake ``bake``'s frames (the client's ``Bake``: the frames claimed, the settings recorded) in chunks of
    ``chunk_size`` on ``client``'s workers; ``flags`` are the command line's (``cli.prepare_scene``), ``threads`` the
    CPU threads a worker renders on (None: the scene's setting, every core; the pixels are the same).
    ``progress(done)`` is called with the frames in the folder as they appear. FarmError for a chunk that failed."""
    from ..output.bake import frame_path

    frames, out_dir = bake.frames, bake.out_dir
    report = FarmReport()

    def finished():
        return [f for f in frames if os.path.exists(frame_path(out_dir, f))]
    report.skipped = finished()
    todo = [c for c in chunks(frames, chunk_size) if not set(c) <= set(report.skipped)]
    digest = sha256(scene_path)
    flags = {**flags, "scene": scene_path}
    futures = {}
    for c in todo:
        task = {"scene": scene_path, "sha256": digest, "flags": flags, "out": out_dir,
                "frames": [c.start, c.stop - 1], "first": frames.start,
                "last": frames.stop - 1, "threads": threads}
        key = f"vpl-gi-bake-{c.start}-{c.stop - 1}-{digest[:8]}-{os.urandom(4).hex()}"
        futures[client.submit(pickle.loads, _runs_when_loaded("operators.cli.farm.render_chunk", task), key=key,
                              pure=False)] = c
    shown = len(report.skipped)
    lost_since = None
    try:
        while futures:
            if client.status != "running":  # reconnecting, or gone
                lost_since = lost_since or time.monotonic()
                if time.monotonic() - lost_since > CONNECT_SECONDS:
                    raise FarmError(f"lost the Dask scheduler ({client.status}); {len(finished())} of {len(frames)} "
                                    f"frames are in {out_dir}: run the same command again to bake the others")
                time.sleep(0.2)
                continue
            lost_since = None
            for future in [f for f in futures if f.status != "pending"]:
                chunk = futures.pop(future)
                if future.status in ("cancelled", "lost"):  # the scheduler forgot it (restarted)
                    raise FarmError(f"the Dask scheduler lost the task of frames {chunk.start}:{chunk.stop - 1}; "
                                    f"{len(finished())} of {len(frames)} frames are in {out_dir}: run the same "
                                    f"command again to bake the others")
                result = _result(future, f"frames {chunk.start}:{chunk.stop - 1}")
                report.rendered += result["rendered"]
                report.replayed += len(result["replayed"])
                report.chunks.append({"frames": [chunk.start, chunk.stop - 1], **{
                    k: result[k] for k in ("host", "pid", "seconds", "rendered", "replayed")}})
            done = len(finished())
            if progress is not None and done != shown:
                progress(done)
                shown = done
            time.sleep(0.2)
    finally:
        if futures and client.status == "running":  # this run failed: the other chunks are not wanted
            client.cancel(list(futures))
        _clear_staging(out_dir)
    report.rendered.sort()
    return report


def _result(future, name: str) -> dict:
    """A finished chunk's report; FarmError, one line naming the chunk, for anything that went wrong."""
    from distributed import KilledWorker
    try:
        result = future.result()
    except KilledWorker:
        raise FarmError(f"{name}: every worker that ran it died (Dask gives up after "
                        f"distributed.scheduler.allowed-failures); see the workers' logs, the finished frames are "
                        f"kept") from None
    except Exception as err:  # a bug on the worker
        raise FarmError(f"{name} failed on a worker: {type(err).__name__}: {' '.join(str(err).split())}") from None
    if "error" in result:
        raise FarmError(result["error"])
    return result


class _Call:
    """Pickles as the call ``function(*args)`` itself, so that ``pickle.loads`` makes it."""

    def __init__(self, function, *args):
        self.function, self.args = function, args

    def __reduce__(self):
        return self.function, self.args


def _runs_when_loaded(name: str, *args) -> bytes:
    """A chunk's task: the pickle of the call ``_on_worker(name, *args)`` with ``_on_worker`` by value (cloudpickle),
    which ``pickle.loads`` on a worker runs. The task's function is thus ``pickle.loads``, which every worker has,
    and a worker without the extension receives the task and says so instead of failing to unpickle it (a worker
    that cannot unpickle a task drops its connection and the task goes round the cluster)."""
    import cloudpickle
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    try:
        return cloudpickle.dumps(_Call(_on_worker, name, *args))
    finally:
        cloudpickle.unregister_pickle_by_value(sys.modules[__name__])


def _on_worker(name: str, *args):
    """The task as a worker runs it: ``vpl_addon.__main__.call(name, *args)``, or an error line if this Python
    cannot load the extension."""
    if "bpy" not in sys.modules:
        # a worker process spawned by one that had imported bpy (a LocalCluster's) inherits its sys.path, whose
        # first folders are bpy's scripts, where `import bpy` finds the scripts' bpy package instead of the module;
        # importing bpy puts them back
        bpy_scripts = os.path.join("bpy", "")
        sys.path[:] = [p for p in sys.path if not (bpy_scripts in p and os.sep + "scripts" in p)]
    try:
        bootstrap = importlib.import_module("vpl_addon.__main__")
    except ImportError as err:
        return {"error": f"the Dask worker on {socket.gethostname()} (pid {os.getpid()}) cannot load the VPL GI "
                         f"extension ({err}): start the workers with the extension's folder on their PYTHONPATH "
                         f"and the bpy module installed, e.g. PYTHONPATH=/path/to/vpl_gi dask worker "
                         f"tcp://SCHEDULER:8786"}
    return bootstrap.call(name, *args)


_ONE_SCENE = threading.Lock()  # bpy holds one scene per process


def render_chunk(task: dict) -> dict:
    """One chunk on this worker: the bake of ``task["frames"]`` (a chunk of the sequence from ``task["first"]``)
    into ``task["out"]``. Returns what it did, or ``{"error": line}`` for a problem the user can fix."""
    with _ONE_SCENE:
        return _render_chunk(task)


def _render_chunk(task: dict) -> dict:
    from ..output.bake import Bake, BakeError
    from .scene_flags import UserError, prepare_scene, verify
    from ..output.render_file import render_to
    from ...vpl_addon.core.memory import heap_for_renders

    heap_for_renders()  # a Dask worker's 64-KiB trim threshold makes its renders 1.8x slower
    host, t0 = socket.gethostname(), time.perf_counter()
    first, last = task["frames"]
    where = f"worker on {host} (pid {os.getpid()}), frames {first}:{last}"
    path = task["scene"]
    if not os.path.isfile(path):
        return {"error": f"{where}: no such file {path}: the .blend must be in a folder every worker sees at the "
                         f"same path"}
    if sha256(path) != task["sha256"]:
        return {"error": f"{where}: {path} is not the file the bake was started with (its SHA-256 differs): a "
                         f"different copy on this worker, or it changed since; start the bake again"}
    staging = os.path.join(task["out"], STAGING_DIR, host)

    def render_frame(target):  # complete frames only under their final names, partial ones in this host's folder
        os.makedirs(staging, exist_ok=True)
        staged = os.path.join(staging, os.path.basename(target))
        render_to(scene, staged, verify)
        os.replace(staged, target)

    try:
        scene = prepare_scene(argparse.Namespace(**task["flags"]))
        if task.get("threads"):  # workers that share a machine share its cores
            scene.render.threads_mode, scene.render.threads = "FIXED", task["threads"]
        bake = Bake(scene, task["out"], range(first, last + 1), first=task["first"], claim=False,
                    last=task["last"])
        report = bake.run(render_frame=render_frame)
    except (UserError, BakeError, OSError) as err:
        return {"error": f"{where}: {err}"}
    return {"host": host, "pid": os.getpid(), "rendered": report.rendered, "skipped": report.skipped,
            "replayed": report.replayed, "seconds": time.perf_counter() - t0}


def _clear_staging(out_dir: str) -> None:
    """This host's staging folder, if no live process of this host writes into it: the partial files of workers
    that died, then the folder."""
    from ..output.render_file import remove_stale_partials
    staging = os.path.join(out_dir, STAGING_DIR, socket.gethostname())
    if not os.path.isdir(staging):
        return
    remove_stale_partials(staging)
    if not os.listdir(staging):
        shutil.rmtree(staging, ignore_errors=True)
        try:
            os.rmdir(os.path.dirname(staging))
        except OSError:
            pass  # other hosts' folders
