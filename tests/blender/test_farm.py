"""Bakes in chunks on a real Dask cluster (``bake --scheduler``, ``operators/cli/farm.py``): a ``distributed.LocalCluster``
on loopback with 2 worker processes, the same bytes as one process, a worker SIGKILLed mid-chunk, a finished bake
re-run, and the bad input a farm meets: an unreachable scheduler, a worker without the extension, a .blend missing
on the worker, a folder holding another bake or being baked."""
import os
import signal
import socket
import subprocess
import sys
import time

import pytest

from conftest import EXAMPLES, ROOT, run_cli

distributed = pytest.importorskip("distributed")

TINY = ("--percentage", "25", "--samples", "1", "--light-samples", "1", "--vpls", "64")


def frames_in(folder):
    return sorted(p.name for p in folder.glob("frame_*.exr"))


def one_line(stderr: str) -> str:
    """The error line of a failed run, checked to be the only thing it printed besides the progress bar."""
    lines = [line for line in stderr.replace("\r", "\n").splitlines() if line.strip() and not line.startswith("bake:")]
    assert len(lines) == 1 and lines[0].startswith("vpl_addon: error: "), stderr
    return lines[0]


@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of 2 single-threaded worker processes on loopback, and a client of it."""
    local = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                     dashboard_address=None, memory_limit=0)
    client = distributed.Client(local, set_as_default=False)
    yield client
    client.close()
    local.close()


def test_chunks_on_two_workers_write_the_bytes_of_one_process_and_a_rerun_renders_nothing(cluster, ext, tmp_path):
    """smc carries its VPL set from frame to frame: 12 frames in chunks of 4 on two workers give the EXRs, byte for
    byte, of the same chunks baked one after another in this process (last chunk first, so each starts without a
    saved state, as the farm's concurrent chunks do) and of one uninterrupted bake; run again, nothing renders."""
    from vpl_gi.operators.output import bake
    from vpl_gi.operators.cli import commands as cli, scene_flags
    flags = ["--method", "smc", "--smc-warmup", "5", *TINY]
    scene_file = EXAMPLES / "seq_moving_light.blend"
    farm = tmp_path / "farm"
    code, stdout, stderr = run_cli("bake", scene_file, "--frames", "1:12", "-o", farm, *flags,
                                   "--scheduler", cluster.scheduler.address, "--chunk-size", "4")
    assert code == 0, stderr
    assert "3 chunks on 2 worker processes" in stdout, stdout
    assert frames_in(farm) == [f"frame_{f:04d}.exr" for f in range(1, 13)]
    assert not (farm / ".farm").exists() and not list(farm.rglob(".partial-*"))
    assert "12/12" in stderr  # the progress bar counted every frame, whichever worker wrote it

    scene = scene_flags.prepare_scene(cli.parser().parse_args(["bake", str(scene_file), "--frames", "1:12", "-o", "x",
                                                        *flags]))
    replayed = []
    for chunk in (range(9, 13), range(5, 9), range(1, 5)):
        report = bake.Bake(scene, str(tmp_path / "chunked"), chunk, first=1).run()
        assert report.rendered == list(chunk)
        replayed.append(report.replayed)
    assert replayed == [list(range(1, 9)), list(range(1, 5)), []]  # smc's state continued, not started cold
    bake.Bake(scene, str(tmp_path / "whole"), range(1, 13)).run()
    for name in frames_in(farm):
        assert (farm / name).read_bytes() == (tmp_path / "chunked" / name).read_bytes(), name
        assert (farm / name).read_bytes() == (tmp_path / "whole" / name).read_bytes(), name

    before = {p: p.stat().st_mtime_ns for p in farm.glob("frame_*.exr")}
    code, stdout, stderr = run_cli("bake", scene_file, "--frames", "1:12", "-o", farm, *flags,
                                   "--scheduler", cluster.scheduler.address, "--chunk-size", "4")
    assert code == 0 and "skipped 12 finished frames" in stdout and "baked 0 frames" in stdout, stdout + stderr
    assert before == {p: p.stat().st_mtime_ns for p in farm.glob("frame_*.exr")}


def test_a_worker_killed_mid_chunk_leaves_no_partial_frame_and_the_bake_completes(cluster, ext, tmp_path):
    """SIGKILL to the worker process rendering a frame: no partial EXR ever carries a final name, Dask runs its chunk
    again (the nanny starts a new worker), and every frame is there, the same bytes as one process writes."""
    from vpl_gi.operators.output import bake
    from vpl_gi.operators.cli import commands as cli, scene_flags
    flags = ["--method", "ir", "--percentage", "50", "--samples", "4", "--light-samples", "2", "--vpls", "256"]
    scene_file = EXAMPLES / "seq_moving_object.blend"
    out = tmp_path / "farm"
    workers = set(cluster.run(os.getpid).values())
    proc = subprocess.Popen([sys.executable, "-m", "vpl_addon", "bake", str(scene_file), "--frames", "1:8", "-o",
                             str(out), *flags, "--scheduler", cluster.scheduler.address, "--chunk-size", "4"],
                            cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    staging = out / ".farm" / socket.gethostname()
    killed, seen = None, set()
    try:
        deadline = time.monotonic() + 120
        while killed is None and proc.poll() is None and time.monotonic() < deadline:
            seen |= set(frames_in(out)) if out.exists() else set()
            for partial in staging.glob(".partial-*.exr") if seen else ():  # a frame in progress after the first
                pid = int(partial.name.split("-")[1])
                if pid in workers:
                    os.kill(pid, signal.SIGKILL)
                    killed = pid
                    break
            time.sleep(0.005)
        assert killed is not None, "no worker was caught rendering a frame"
        stdout, stderr = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert proc.returncode == 0, stderr
    assert killed not in set(cluster.run(os.getpid).values())
    assert frames_in(out) == [f"frame_{f:04d}.exr" for f in range(1, 9)]
    assert not list(out.rglob(".partial-*")) and not (out / ".farm").exists()
    scene = scene_flags.prepare_scene(cli.parser().parse_args(["bake", str(scene_file), "--frames", "1:8", "-o", "x",
                                                        *flags]))
    bake.Bake(scene, str(tmp_path / "whole"), range(1, 9)).run()
    for name in frames_in(out):
        assert (out / name).read_bytes() == (tmp_path / "whole" / name).read_bytes(), name


def test_an_unreachable_scheduler_is_one_line_and_writes_nothing(tmp_path):
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "bake"
    code, stdout, stderr = run_cli("bake", EXAMPLES / "seq_moving_light.blend", "--frames", "1:4", "-o", out, *TINY,
                                   "--scheduler", f"tcp://127.0.0.1:{port}")
    assert code == 2 and one_line(stderr).startswith("vpl_addon: error: cannot reach")
    assert f"cannot reach the Dask scheduler at tcp://127.0.0.1:{port}" in stderr
    assert not out.exists()


def test_a_worker_without_the_extension_says_so_in_one_line(tmp_path):
    """A `dask worker` whose Python has bpy and Dask but not the extension on its path."""
    scheduler = distributed.LocalCluster(n_workers=0, host="127.0.0.1", dashboard_address=None)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", scheduler.scheduler_address,
                               "--nthreads", "1", "--no-nanny", "--no-dashboard"], cwd=tmp_path, env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        with distributed.Client(scheduler, set_as_default=False) as client:
            client.wait_for_workers(1, timeout=60)
        out = tmp_path / "bake"
        code, stdout, stderr = run_cli("bake", EXAMPLES / "seq_moving_light.blend", "--frames", "1:4", "-o", out,
                                       *TINY, "--scheduler", scheduler.scheduler_address)
    finally:
        worker.kill()
        worker.wait()
        scheduler.close()
    assert code == 2 and "cannot load" in one_line(stderr), stderr
    assert "cannot load the VPL GI extension (No module named 'vpl_addon')" in stderr
    assert frames_in(out) == [] and not list(out.glob(".bake-claims/*"))


def test_a_blend_missing_on_the_worker_is_one_line_and_renders_nothing(cluster, tmp_path):
    """A chunk's task names a .blend the worker cannot see (a shared folder not mounted there): the worker says so
    before it opens or writes anything."""
    import pickle
    from vpl_gi.operators.cli import farm
    missing = tmp_path / "not_mounted" / "scene.blend"
    task = {"scene": str(missing), "sha256": farm.sha256(EXAMPLES / "seq_moving_light.blend"), "flags": {},
            "out": str(tmp_path / "bake"), "frames": [1, 4], "first": 1}
    future = cluster.submit(pickle.loads, farm._runs_when_loaded("operators.cli.farm.render_chunk", task), pure=False)
    with pytest.raises(farm.FarmError) as err:
        farm._result(future, "frames 1:4")
    message = str(err.value)
    assert "\n" not in message and f"frames 1:4: no such file {missing}" in message and "every worker sees" in message
    assert not (tmp_path / "bake").exists()


def test_a_folder_holding_another_bake_or_being_baked_is_refused_in_one_line(cluster, tmp_path):
    out = tmp_path / "bake"
    scene_file = EXAMPLES / "seq_moving_light.blend"
    assert run_cli("bake", scene_file, "--frames", "1:2", "-o", out, *TINY, "--method", "ir")[0] == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    code, _, stderr = run_cli("bake", scene_file, "--frames", "1:2", "-o", out, *TINY, "--method", "bidir",
                              "--scheduler", cluster.scheduler.address)
    assert code == 2 and "holds a bake with other settings" in one_line(stderr), stderr
    assert before == {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}

    # a bake of frames 2:5 is running (this process stands for it): a second one of frames 4:6 is refused
    claims = out / ".bake-claims"
    claims.mkdir(exist_ok=True)
    (claims / "2-5.json").write_text(f'{{"host": "{socket.gethostname()}", "pid": {os.getpid()}, "frames": [2, 5]}}')
    code, _, stderr = run_cli("bake", scene_file, "--frames", "4:6", "-o", out, *TINY, "--method", "ir",
                              "--workers", "1")
    assert code == 2 and f"is being baked (frames 2:5) by process {os.getpid()}" in one_line(stderr), stderr
    assert frames_in(out) == ["frame_0001.exr", "frame_0002.exr"]
    # its owner gone, the claim is stale: frames 3:4 of a chunk of the sequence bake beside frames 1:2
    (claims / "2-5.json").write_text(f'{{"host": "{socket.gethostname()}", "pid": 999999999, "frames": [2, 5]}}')
    code, stdout, stderr = run_cli("bake", scene_file, "--frames", "3:4", "--sequence-start", "1", "-o", out, *TINY,
                                   "--method", "ir")
    assert code == 0, stderr
    assert frames_in(out) == [f"frame_{f:04d}.exr" for f in range(1, 5)] and not list(claims.iterdir())


def test_a_scheduler_restart_and_a_rerun_complete_the_bake_without_rendering_finished_frames(ext, tmp_path):
    """The scheduler (and its workers) go away mid-bake: the command ends with one line; against a new scheduler the
    same command renders only the missing frames, and they are the frames of one uninterrupted bake."""
    from vpl_gi.operators.output import bake
    from vpl_gi.operators.cli import commands as cli, scene_flags
    flags = ["--method", "ir", "--percentage", "50", "--samples", "4", "--light-samples", "2", "--vpls", "256"]
    scene_file = EXAMPLES / "seq_moving_object.blend"
    out = tmp_path / "farm"

    def command(address):
        return [sys.executable, "-m", "vpl_addon", "bake", str(scene_file), "--frames", "1:8", "-o", str(out),
                *flags, "--scheduler", address, "--chunk-size", "4"]
    first = distributed.LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=None,
                                     memory_limit=0)
    proc = subprocess.Popen(command(first.scheduler_address), cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while proc.poll() is None and time.monotonic() < deadline and not frames_in(out):
            time.sleep(0.01)
        with distributed.Client(first, set_as_default=False) as client:
            workers = client.run(os.getpid).values()
        for pid in workers:  # the cluster goes down at once, its chunks unfinished
            os.kill(pid, signal.SIGKILL)
        first.close()
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 2 and "run the same command again" in one_line(stderr), stdout + stderr
    done = {p.name: p.stat().st_mtime_ns for p in out.glob("frame_*.exr")}
    assert 1 <= len(done) < 8 and not list((out / ".bake-claims").iterdir())

    second = distributed.LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=None,
                                      memory_limit=0)
    try:
        proc = subprocess.run(command(second.scheduler_address), cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)},
                              capture_output=True, text=True, timeout=300)
    finally:
        second.close()
    assert proc.returncode == 0, proc.stderr
    assert f"skipped {len(done)} finished frames" in proc.stdout and f"baked {8 - len(done)} frames" in proc.stdout
    assert done == {name: (out / name).stat().st_mtime_ns for name in done}  # not rendered again
    scene = scene_flags.prepare_scene(cli.parser().parse_args(["bake", str(scene_file), "--frames", "1:8", "-o", "x",
                                                        *flags]))
    bake.Bake(scene, str(tmp_path / "whole"), range(1, 9)).run()
    assert frames_in(out) == frames_in(tmp_path / "whole") == [f"frame_{f:04d}.exr" for f in range(1, 9)]
    for name in frames_in(out):
        assert (out / name).read_bytes() == (tmp_path / "whole" / name).read_bytes(), name
