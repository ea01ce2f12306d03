"""Which GPU renders: `--device` as the user means it, and what a report says about the device that ran.

`egl_device_index` turns `--device` into the EGL device index that moderngl opens: a plain index, or
cuda:N, the GPU that CUDA numbers N, found through the NVIDIA driver's EGL_NV_device_cuda, since EGL's
device order is not CUDA's on a machine with several GPUs. `describe` gives the GL strings and a renderer
family (golden sets and comparisons key on it); `nvml_clocks` gives the clocks, clock-event reasons and
load around each timing, where NVML is there, since a down-clocked or throttled GPU makes a slower time
that is not the technique's.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import functools
import os
import re
from typing import NamedTuple

from vdmbake.errors import InputError

# EGL 1.5 and extension enums (Khronos eglext.h)
EGL_EXTENSIONS = 0x3055
EGL_CUDA_DEVICE_NV = 0x323A  # EGL_NV_device_cuda
EGL_DRM_DEVICE_FILE_EXT = 0x3233  # EGL_EXT_device_drm
EGL_RENDERER_EXT = 0x335F  # EGL_EXT_device_query_name

_SPEC = re.compile(r"(cuda:)?([0-9]+)")  # [0-9], not \d: int() rejects some of what \d accepts

# EGLBoolean is unsigned int, EGLint int32, EGLDeviceEXT a pointer, EGLAttrib intptr_t (ssize_t here)
_QUERY_DEVICES = ctypes.CFUNCTYPE(ctypes.c_uint, ctypes.c_int32, ctypes.POINTER(ctypes.c_void_p),
                                  ctypes.POINTER(ctypes.c_int32))
_QUERY_ATTRIB = ctypes.CFUNCTYPE(ctypes.c_uint, ctypes.c_void_p, ctypes.c_int32, ctypes.POINTER(ctypes.c_ssize_t))
_QUERY_STRING = ctypes.CFUNCTYPE(ctypes.c_char_p, ctypes.c_void_p, ctypes.c_int32)


def egl_device_index(spec: str | None) -> int | None:
    """The EGL device index that `--device spec` names, for moderngl's `device_index`.

    None or "": None (no choice; glcontext then opens EGL device 0). "N": EGL device N, as enumerated by
    eglQueryDevicesEXT. "cuda:N": the EGL device whose EGL_CUDA_DEVICE_NV is N, i.e. the CUDA device
    ordinal N as the NVIDIA EGL driver reports it (CUdevice N of this process, so after
    CUDA_VISIBLE_DEVICES; see `_egl_devices`)."""
    if spec is None or spec == "":
        return None
    m = _SPEC.fullmatch(spec)
    if m is None:
        raise InputError(f"--device {spec!r}: expected an EGL device index (0, 1, ...) or cuda:N, the GPU that "
                         "CUDA numbers N (cuda:0, cuda:1, ...).")
    if not m.group(1):
        return int(m.group(2))
    cuda = int(m.group(2))
    devices = _egl_devices()
    by_cuda = {d.cuda: i for i, d in enumerate(devices) if d.cuda is not None}
    listing = "; ".join(f"{i}: {d.label}" for i, d in enumerate(devices)) or "none"
    if not any(d.nv_cuda for d in devices):
        raise InputError(f"--device cuda:{cuda} needs an NVIDIA driver exposing EGL_NV_device_cuda, and no EGL device "
                         f"here lists it; this machine's EGL devices: {listing}. Use --device N with an EGL device "
                         "index instead.")
    if cuda not in by_cuda:
        found = ", ".join(f"cuda:{c} (EGL device {i})" for c, i in sorted(by_cuda.items())) or "none"
        hidden = [str(i) for i, d in enumerate(devices) if d.nv_cuda and d.cuda is None]
        visible = os.environ.get("CUDA_VISIBLE_DEVICES")
        raise InputError(
            f"--device cuda:{cuda}: no EGL device is CUDA device {cuda}; the CUDA devices EGL reports are {found}"
            + (f", and NVIDIA EGL device(s) {', '.join(hidden)} have no CUDA number" if hidden else "")
            + (f" (CUDA_VISIBLE_DEVICES={visible!r} is set: CUDA sees only the GPUs it lists, numbered from 0)"
               if visible is not None else "") + ". Use one of those, or --device N with an EGL device index.")
    return by_cuda[cuda]


class _EglDevice(NamedTuple):
    label: str  # its name (or DRM file) and its device extensions
    nv_cuda: bool  # lists EGL_NV_device_cuda
    cuda: int | None  # its EGL_CUDA_DEVICE_NV, where the driver gives one


def _egl_devices() -> list[_EglDevice]:
    """The EGL devices, in eglQueryDevicesEXT's order.

    The order is the one glcontext (moderngl's EGL backend) indexes with `device_index`: its egl.cpp
    calls eglQueryDevicesEXT(0, NULL, &n), then eglQueryDevicesEXT(n, devices, &n) and opens
    devices[device_index] with eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, ...) (glcontext 3.x,
    glcontext/egl.cpp, meth_create_context, the standalone branch). We load the same library it
    dlopens (glcontext/__init__.py: $GLCONTEXT_LINUX_LIBEGL, else find_library("EGL")), and libglvnd's
    eglQueryDevicesEXT lists each vendor's devices in vendor order (src/EGL/libegl.c), so both see one
    list. glcontext also lets $GLCONTEXT_DEVICE_INDEX override the index it is given.

    EGL_CUDA_DEVICE_NV is the driver's CUdevice for the EGL device, and CUDA_VISIBLE_DEVICES applies to
    it but not to EGL's list: seen on one H100 (driver 580.159.04), a GPU that CUDA_VISIBLE_DEVICES hides
    ("", "1", "-1") stays EGL device 0 and still lists EGL_NV_device_cuda, but the attribute query fails;
    with "0" or the GPU's UUID it is 0. That several visible GPUs are renumbered in CUDA_VISIBLE_DEVICES'
    order, as CUdevice is, was not seen (one GPU)."""
    name = os.environ.get("GLCONTEXT_LINUX_LIBEGL") or ctypes.util.find_library("EGL")
    try:
        lib = ctypes.CDLL(name) if name else None
    except OSError:
        lib = None
    if lib is None:
        raise InputError(f"--device cuda:N: cannot load libEGL ({name or 'not found'}); install libegl1 "
                         "(libglvnd) and the GPU's EGL driver, or use --device N.")
    lib.eglQueryString.argtypes = [ctypes.c_void_p, ctypes.c_int32]
    lib.eglQueryString.restype = ctypes.c_char_p
    lib.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    lib.eglGetProcAddress.restype = ctypes.c_void_p
    # client extensions: queried on EGL_NO_DISPLAY (EGL_EXT_client_extensions)
    client = (lib.eglQueryString(None, EGL_EXTENSIONS) or b"").decode().split()
    pointers = [lib.eglGetProcAddress(f) for f in (b"eglQueryDevicesEXT", b"eglQueryDeviceAttribEXT",
                                                   b"eglQueryDeviceStringEXT")]
    base = "EGL_EXT_device_base" in client  # the older name of enumeration + query together
    if not (base or {"EGL_EXT_device_enumeration", "EGL_EXT_device_query"} <= set(client)) or not all(pointers):
        raise InputError(f"--device cuda:N: {name} cannot enumerate EGL devices (it lacks EGL_EXT_device_enumeration "
                         "/ EGL_EXT_device_query); use --device N, or install libglvnd's libEGL.")
    query_devices, query_attrib, query_string = (kind(p) for kind, p in zip(
        (_QUERY_DEVICES, _QUERY_ATTRIB, _QUERY_STRING), pointers))
    count = ctypes.c_int32(0)
    if not query_devices(0, None, ctypes.byref(count)):
        raise InputError(f"--device cuda:N: eglQueryDevicesEXT failed in {name}; use --device N.")
    handles = (ctypes.c_void_p * max(count.value, 1))()
    if not query_devices(len(handles), handles, ctypes.byref(count)):
        raise InputError(f"--device cuda:N: eglQueryDevicesEXT failed in {name}; use --device N.")
    devices = []
    for handle in handles[:count.value]:
        extensions = (query_string(handle, EGL_EXTENSIONS) or b"").decode()
        names = extensions.split()
        label = None
        if "EGL_EXT_device_query_name" in names:
            label = query_string(handle, EGL_RENDERER_EXT)
        if not label and "EGL_EXT_device_drm" in names:
            label = query_string(handle, EGL_DRM_DEVICE_FILE_EXT)
        label = f"{(label or b'unnamed').decode()} [{extensions or 'no device extensions'}]"
        ordinal = ctypes.c_ssize_t(-1)
        nv_cuda = "EGL_NV_device_cuda" in names
        # the driver lists the extension but fails the query for a GPU that CUDA_VISIBLE_DEVICES hides
        cuda = nv_cuda and query_attrib(handle, EGL_CUDA_DEVICE_NV, ctypes.byref(ordinal))
        devices.append(_EglDevice(label, nv_cuda, ordinal.value if cuda else None))
    return devices


# (substring of "renderer vendor" lowercased, family); first match wins: the software and layered
# drivers first, as their strings may name the hardware under them (zink on NVIDIA says NVIDIA)
_FAMILIES = (("llvmpipe", "llvmpipe"), ("softpipe", "softpipe"), ("zink", "zink"), ("nvidia", "nvidia"),
             ("amd", "amd"), ("radeon", "amd"), ("intel", "intel"), ("apple", "apple"))


def describe(ctx) -> dict:
    """The GL device of `ctx` as plain JSON data: vendor, renderer, version, and family, a short stable
    name for golden sets and comparisons ("llvmpipe", "nvidia", "amd", "intel", ..., else the renderer
    string lowercased)."""
    vendor, renderer, version = (ctx.info[k] for k in ("GL_VENDOR", "GL_RENDERER", "GL_VERSION"))
    text = f"{renderer} {vendor}".lower()
    family = next((f for key, f in _FAMILIES if key in text), renderer.lower())
    return {"vendor": vendor, "renderer": renderer, "version": version, "family": family}


# nvml.h nvmlClocksEventReason* (formerly nvmlClocksThrottleReason*) bits
_REASONS = {0x1: "gpu_idle", 0x2: "applications_clocks_setting", 0x4: "sw_power_cap", 0x8: "hw_slowdown",
            0x10: "sync_boost", 0x20: "sw_thermal_slowdown", 0x40: "hw_thermal_slowdown",
            0x80: "hw_power_brake_slowdown", 0x100: "display_clock_setting", 0x200: "board_limit",
            0x400: "reliability"}


@functools.cache
def _nvml():
    """pynvml, initialised once per process (nvmlInit costs far more than the queries), or None where it
    does not import (nvidia-ml-py is optional) or NVML does not start (no NVIDIA driver)."""
    try:
        import pynvml

        pynvml.nvmlInit()
    except Exception:  # ImportError, pynvml.NVMLError (no libnvidia-ml, driver not loaded), OSError
        return None
    return pynvml


def nvml_clocks() -> dict | None:
    """{"driver": version, "gpus": [per GPU in NVML's index order: index, name, pci_bus_id, sm_clock_mhz,
    sm_clock_max_mhz, mem_clock_mhz, clock_reasons (names of the current clock-event reasons),
    util_pct (GPU busy, % of NVML's last sample period)]}; None without NVIDIA's NVML or on any NVML
    error. NVML numbers GPUs by PCI bus, not as CUDA does (hence pci_bus_id)."""
    nv = _nvml()
    if nv is None:
        return None
    try:
        return {"driver": _text(nv.nvmlSystemGetDriverVersion()),
                "gpus": [_gpu(nv, i) for i in range(nv.nvmlDeviceGetCount())]}
    except nv.NVMLError:
        return None


def _gpu(nv, index: int) -> dict:
    h = nv.nvmlDeviceGetHandleByIndex(index)
    # the event-reasons call replaced the throttle-reasons one (same bits); older pynvml has only the latter
    reasons = getattr(nv, "nvmlDeviceGetCurrentClocksEventReasons", None) or nv.nvmlDeviceGetCurrentClocksThrottleReasons
    bits = reasons(h)
    unknown = bits & ~sum(_REASONS)
    return {"index": index, "name": _text(nv.nvmlDeviceGetName(h)),
            "pci_bus_id": _text(nv.nvmlDeviceGetPciInfo(h).busId),
            "sm_clock_mhz": nv.nvmlDeviceGetClockInfo(h, nv.NVML_CLOCK_SM),
            "sm_clock_max_mhz": nv.nvmlDeviceGetMaxClockInfo(h, nv.NVML_CLOCK_SM),
            "mem_clock_mhz": nv.nvmlDeviceGetClockInfo(h, nv.NVML_CLOCK_MEM),
            "clock_reasons": [name for bit, name in _REASONS.items() if bits & bit] + ([hex(unknown)] if unknown else []),
            "util_pct": nv.nvmlDeviceGetUtilizationRates(h).gpu}


def _text(value) -> str:
    """pynvml gives bytes or str depending on its version."""
    return value.decode() if isinstance(value, bytes) else value
