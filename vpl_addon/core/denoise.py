"""The finished picture denoised with Intel Open Image Denoise (OIDN, through the ``pyoidn`` wheel), as Cycles'
render denoiser does it: the "RT" filter on the HDR colour, guided by the first surfaces' albedo and normal.

The guides are Cycles' ``Denoising Albedo`` (diffuse plus glossy colour plus emission, so that an emitter's edges
are kept) and ``Denoising Normal`` (the shading normal in camera space, x right, y up, z forward), per pixel the mean
over its samples. They are nearly noise-free here (no path is traced for them), but texture detail and anti-aliased
edges make them differ from sample to sample, so by default they are prefiltered by OIDN first, as its documentation
recommends for guides that are not clean ("cleanAux").

How, and at what cost, is chosen as in Cycles, with Cycles' names (its render and viewport Denoising settings, and
the compositor Denoise node's): the *prefilter* is ``ACCURATE`` (the guides denoised first, three filter runs),
``FAST`` (one run that takes the guides as noisy) or ``NONE`` (one run that takes them as clean); the *quality* is
OIDN's ``HIGH`` (its large network with clean guides), ``BALANCED`` or ``FAST``. At 256 x 256 on 2 cores
``ACCURATE`` / ``HIGH`` takes 0.72 s, ``FAST`` / ``HIGH`` 0.11 s.

OIDN's network is not symmetric under a vertical flip (the same image upside down denoises 2-3 % differently, in
rMAE), so the images go to it bottom row first, the way Blender holds images: a compositor Denoise node fed by our
passes then gives exactly our denoised Combined.

Our guides are means of noise-free values (no path is traced for them), so what makes them noisy is having few
samples per pixel over an edge or a texture: from ``CLEAN_GUIDES`` camera samples per pixel on, *Accurate* does not
denoise them first (``prefilter_for``) but hands them to the colour's run as clean, as *None* does, for the same
picture in a third of the time.

*Indirect light apart* (the render's ``denoise_indirect_apart``, on by default) goes one step past Cycles: the
indirect light in Combined (the colours times Diffuse and Glossy Indirect) and the rest are denoised each on its own,
with the same guides, and added. The gather's noise is not the direct light's, and one network run over their sum
leaves more of both: Combined's rMAE is 3.5-7 % lower on the four Cornell boxes at 16 and 64 samples, 10-12.5 % on the
PBR box and cornell_measured, 3.5-5 % in the living room, 0-2 % on the Veach scenes and the corridor (2 seeds;
``bench/denoise_passes.py`` denoises both ways), for one OIDN run more (0.27 s at 256 x 256). A compositor Denoise
node on Noisy Image, Cycles' own set-up, denoises Combined whole: it gives our picture with this off, and one
0.2-3.9 % rMAE from it with it on (the most at few samples and small images).

Progress and cancelling (ESC) reach into OIDN's filters through its progress monitor, which ``pyoidn`` declares the
type of but does not wrap: the setter is declared on pyoidn's cffi interface (``_progress_setter``).
"""
from __future__ import annotations

import functools
from typing import Callable

import numpy as np


# OIDN's scratch memory per filter run, in MB: above it OIDN denoises in overlapping tiles, with the same result. Left
# to itself it takes 1.45 GB at 1920 x 1080 (and grows with the image); 1 GB costs 9 % more time there, 768 MB 50 %.
SCRATCH_MB = 1024


# camera samples per pixel from which Accurate takes the guides as clean (``prefilter_for``). Measured on the four
# Cornell boxes and the corridor (2 seeds), Combined denoised with the guides prefiltered and not, at 256 x 256: at
# 64 samples the two pictures differ by rMAE 0.0002-0.0003 and their rMAE against the references by at most 0.0001;
# at 32 by 0.0005-0.0032, at most 1.4 % of the error; at 16 by up to 0.0064, 2-3 % more error; at 4 7-10 % more.
# Skipping the two guide runs saves 0.55 s there (0.26 s a run; 8 s at 1024 x 1024).
CLEAN_GUIDES = 32

# Cycles' Denoising Prefilter and Denoising Quality (OIDN's ``OIDN_QUALITY_*``), best first
PREFILTERS = ("ACCURATE", "FAST", "NONE")
QUALITIES = ("HIGH", "BALANCED", "FAST")


class DenoiserMissing(RuntimeError):
    """OIDN cannot be loaded on this system (the message says why)."""


class DenoiseCancelled(Exception):
    """``progress`` returned False while OIDN ran."""


def _oidn():
    try:
        import pyoidn
    except Exception as err:  # ImportError, or its shared library failing to load
        raise DenoiserMissing(f"OpenImageDenoise is not available ({type(err).__name__}: {err})") from err
    return pyoidn


def available() -> bool:
    """Whether OIDN loads on this system (``denoise`` would run)."""
    try:
        _oidn()
    except DenoiserMissing:
        return False
    return True


def denoise(color: np.ndarray, albedo: np.ndarray, normal: np.ndarray, threads: int | None = None,
            progress: Callable[[float], bool] | None = None, prefilter: str = "ACCURATE",
            quality: str = "HIGH", apart: np.ndarray | None = None) -> np.ndarray:
    """(H,W,3) float32 denoised HDR ``color`` (linear, non-negative) guided by ``albedo`` and ``normal`` (H,W,3);
    rows top first, as the passes are; on ``threads`` CPU threads (None: OIDN's choice, every core), with Cycles'
    ``prefilter`` and ``quality`` (``PREFILTERS``, ``QUALITIES``). ``apart`` (H,W,3), a part of ``color`` (the
    render's indirect light): it and the rest of ``color`` are denoised each on its own, with the same guides, and
    added. ``progress(fraction)`` is called as OIDN works (over its filter runs: with ``ACCURATE`` the two guides,
    then the colour, or its two parts); False stops it (``DenoiseCancelled``)."""
    check(prefilter, quality)
    oidn = _oidn()
    device = oidn.Device(oidn.OIDN_DEVICE_TYPE_CPU)
    if threads:
        device.set_int("numThreads", int(threads))
    device.commit()
    level = getattr(oidn, f"OIDN_QUALITY_{quality}")
    images = [color] if apart is None else [np.maximum(np.asarray(color, np.float32) - apart, 0.0), apart]
    first = 2 if prefilter == "ACCURATE" else 0  # the colour's first filter run
    runs = first + len(images)

    def part(index):  # the share of the whole that filter run ``index`` (of ``runs``) is
        return None if progress is None else (lambda done: progress((index + done) / runs))
    try:
        guides = {"albedo": _float3(albedo), "normal": _float3(normal)}
        if prefilter == "ACCURATE":
            guides = {name: _filtered(oidn, device, {name: image}, part(index), level)
                      for index, (name, image) in enumerate(guides.items())}
        return sum(_filtered(oidn, device, {"color": _float3(image), **guides}, part(first + index), level, hdr=True,
                             clean_aux=prefilter != "FAST") for index, image in enumerate(images))[::-1]
    finally:
        device.release()


def denoise_lightmap(color: np.ndarray, threads: int | None = None,
                     progress: Callable[[float], bool] | None = None, quality: str = "HIGH") -> np.ndarray:
    """(H,W,3) float32 baked light ``color`` (H,W,3, linear, rows top first) denoised by OIDN's lightmap filter
    (``RTLightmap``: HDR colour alone, no guides, as OIDN documents it for baked irradiance), on ``threads`` CPU
    threads, at Cycles' ``quality``; ``progress`` as ``denoise``'s."""
    check("NONE", quality)
    oidn = _oidn()
    device = oidn.Device(oidn.OIDN_DEVICE_TYPE_CPU)
    if threads:
        device.set_int("numThreads", int(threads))
    device.commit()
    try:
        return _filtered(oidn, device, {"color": _float3(color)}, progress, getattr(oidn, f"OIDN_QUALITY_{quality}"),
                         "RTLightmap")[::-1]
    finally:
        device.release()


def prefilter_for(prefilter: str, samples: int) -> str:
    """The prefilter that gives Cycles' ``prefilter`` on our guides averaged over ``samples`` camera samples per
    pixel: *Accurate* runs as *None* from ``CLEAN_GUIDES`` samples on, where the guides are clean; the others as
    they are."""
    return "NONE" if prefilter == "ACCURATE" and samples >= CLEAN_GUIDES else prefilter


def check(prefilter: str, quality: str) -> None:
    """ValueError naming the setting unless ``prefilter`` and ``quality`` are Cycles' names."""
    for what, value, names in (("prefilter", prefilter, PREFILTERS), ("quality", quality, QUALITIES)):
        if value not in names:
            raise ValueError(f"unknown denoising {what} {value!r}; choose one of {', '.join(names)}")


@functools.cache
def _progress_setter():
    """pyoidn's cffi interface and OIDN's ``oidnSetFilterProgressMonitorFunction`` on it (declared again without
    complaint when this module is loaded twice, as the extension and as the engine package)."""
    from pyoidn import capi
    capi.oidn_ffi.cdef("void oidnSetFilterProgressMonitorFunction(OIDNFilter, OIDNProgressMonitorFunction, void*);",
                       override=True)
    return capi.oidn_ffi, capi.oidn_Capi.oidnSetFilterProgressMonitorFunction


def _float3(image: np.ndarray) -> np.ndarray:
    """The RGB of an (H,W,C) image, rows top first, as OIDN's contiguous float3 input, bottom row first."""
    return np.ascontiguousarray(np.nan_to_num(np.asarray(image, np.float32)[::-1, :, :3], nan=0.0, posinf=0.0))


def _filtered(oidn, device, images: dict[str, np.ndarray], keep_going: Callable[[float], bool] | None,
              quality: int, kind: str = "RT", **flags) -> np.ndarray:
    """One run of OIDN's filter ``kind`` (``RT``, or ``RTLightmap``) on ``images`` (OIDN input names: color,
    albedo, normal) at OIDN's ``quality``; its output has the shape of the first. A guide given alone is denoised
    itself (OIDN's prefiltering of auxiliary images). ``keep_going(done)`` hears the run's progress (0 to 1) and
    stops it by returning False."""
    first = next(iter(images.values()))
    height, width = first.shape[:2]
    out = np.zeros_like(first)
    rt = oidn.Filter(device, kind)
    stopped = []
    if keep_going is not None:
        ffi, set_monitor = _progress_setter()

        def monitor(_user, done):
            if keep_going(float(done)) is False:
                stopped.append(done)
                return False
            return True
        callback = ffi.callback("bool(void*, double)", monitor)  # an error in it prints and stops OIDN
        set_monitor(rt._filter, callback, ffi.NULL)  # pyoidn's handle of the filter
    try:
        for name, image in images.items():
            rt.set_image(name, image, oidn.OIDN_FORMAT_FLOAT3, width, height)
        rt.set_image("output", out, oidn.OIDN_FORMAT_FLOAT3, width, height)
        for name, value in flags.items():
            rt.set_bool("cleanAux" if name == "clean_aux" else name, value)
        rt.set_int("quality", quality)
        rt.set_int("maxMemoryMB", SCRATCH_MB)
        rt.commit()
        rt.execute()
        message = device.get_error()  # None, or OIDN's message
        if stopped:
            raise DenoiseCancelled()
        if message:
            raise RuntimeError(f"OpenImageDenoise failed: {message}")
    finally:
        rt.release()
    return np.maximum(np.nan_to_num(out, nan=0.0, posinf=0.0), 0.0) if "color" in images else out
