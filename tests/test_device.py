"""vdmrender.gpu.device: --device parsing (EGL index or cuda:N), the GL device description, NVML clocks."""
import sys
import types

import pytest

from vdmbake.errors import InputError
from vdmrender.gpu import device


def test_spec_default_and_index():
    assert device.egl_device_index(None) is None
    assert device.egl_device_index("") is None
    assert device.egl_device_index("0") == 0
    assert device.egl_device_index("12") == 12


@pytest.mark.parametrize("spec", ["cuda:x", "gpu1", "-1", "cuda:-1", "cuda:", "cuda", "1.5", " 1", "CUDA:0", "cuda:0:1",
                                  "²"])
def test_malformed_spec(spec):
    with pytest.raises(InputError, match=r"expected an EGL device index \(0, 1, \.\.\.\) or cuda:N") as e:
        device.egl_device_index(spec)
    assert repr(spec) in str(e.value)


def test_egl_devices_enumerate():
    """ctypes really reaches eglQueryDevicesEXT here: Mesa lists at least its software device."""
    devices = device._egl_devices()
    assert devices, "no EGL device enumerated"
    assert all(d.label for d in devices)


def test_enumeration_is_glcontexts():
    """glcontext counts the same devices: the index one past ours is the first it refuses."""
    import moderngl

    n = len(device._egl_devices())
    with pytest.raises(Exception, match=f"requested device index {n}, but found {n} devices"):
        moderngl.create_context(standalone=True, backend="egl", require=430, device_index=n)


def test_cuda_without_nvidia_egl():
    if any(d.nv_cuda for d in device._egl_devices()):
        pytest.skip("this machine's EGL has EGL_NV_device_cuda (see test_cuda_index_opens_nvidia)")
    with pytest.raises(InputError) as e:
        device.egl_device_index("cuda:0")
    msg = str(e.value)
    assert "EGL_NV_device_cuda" in msg and "--device N" in msg
    for i, d in enumerate(device._egl_devices()):
        assert f"{i}: {d.label}" in msg
    if "llvmpipe" in _renderer():
        assert "EGL_MESA_device_software" in msg


def test_cuda_index_opens_nvidia():
    """With NVIDIA's EGL, cuda:N names an EGL index whose context is NVIDIA's, and an absent N lists those found."""
    if all(d.cuda is None for d in device._egl_devices()):
        pytest.skip("no EGL device with a CUDA number (EGL_NV_device_cuda) here")
    import moderngl

    index = device.egl_device_index("cuda:0")
    ctx = moderngl.create_context(standalone=True, backend="egl", require=430, device_index=index)
    try:
        assert device.describe(ctx)["family"] == "nvidia"
    finally:
        ctx.release()
    with pytest.raises(InputError, match=r"no EGL device is CUDA device 99; the CUDA devices EGL reports are cuda:0 "):
        device.egl_device_index("cuda:99")


_MESA = device._EglDevice("unnamed [EGL_MESA_device_software]", False, None)
_H100 = device._EglDevice("NVIDIA H100 [EGL_NV_device_cuda]", True, 0)
_H200 = device._EglDevice("NVIDIA H200 [EGL_NV_device_cuda]", True, 1)
_HIDDEN = device._EglDevice("NVIDIA H100 [EGL_NV_device_cuda]", True, None)  # CUDA_VISIBLE_DEVICES hides it


@pytest.mark.parametrize("devices, spec, index", [
    ([_MESA, _H100, _H200], "cuda:0", 1),
    ([_MESA, _H100, _H200], "cuda:1", 2),
    ([_H200, _H100], "cuda:0", 1),  # EGL's order is not CUDA's
    ([_HIDDEN, _H200], "cuda:1", 1),
])
def test_cuda_index_mapping(monkeypatch, devices, spec, index):
    monkeypatch.setattr(device, "_egl_devices", lambda: devices)
    assert device.egl_device_index(spec) == index


def test_cuda_index_absent(monkeypatch):
    monkeypatch.delenv("CUDA_VISIBLE_DEVICES", raising=False)
    monkeypatch.setattr(device, "_egl_devices", lambda: [_MESA, _H200, _H100])
    with pytest.raises(InputError) as e:
        device.egl_device_index("cuda:2")
    assert str(e.value) == ("--device cuda:2: no EGL device is CUDA device 2; the CUDA devices EGL reports are "
                            "cuda:0 (EGL device 2), cuda:1 (EGL device 1). Use one of those, or --device N with an "
                            "EGL device index.")


def test_cuda_index_hidden(monkeypatch):
    """NVIDIA's EGL keeps a GPU that CUDA_VISIBLE_DEVICES hides, with no CUDA number: the message says why."""
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "")
    monkeypatch.setattr(device, "_egl_devices", lambda: [_HIDDEN])
    with pytest.raises(InputError, match=r"are none, and NVIDIA EGL device\(s\) 0 have no CUDA number "
                                         r"\(CUDA_VISIBLE_DEVICES='' is set: CUDA sees only the GPUs it lists"):
        device.egl_device_index("cuda:0")


def test_cuda_without_nvidia_lists_devices(monkeypatch):
    monkeypatch.setattr(device, "_egl_devices", lambda: [_MESA, device._EglDevice("/dev/dri/card1 [EGL_EXT_device_drm]",
                                                                                  False, None)])
    with pytest.raises(InputError) as e:
        device.egl_device_index("cuda:0")
    assert str(e.value) == ("--device cuda:0 needs an NVIDIA driver exposing EGL_NV_device_cuda, and no EGL device "
                            "here lists it; this machine's EGL devices: 0: unnamed [EGL_MESA_device_software]; "
                            "1: /dev/dri/card1 [EGL_EXT_device_drm]. Use --device N with an EGL device index instead.")


def _renderer() -> str:
    from vdmrender.gpu import gl

    ctx = gl.create_context()
    try:
        return ctx.info["GL_RENDERER"]
    finally:
        ctx.release()


def test_describe_real_context(ctx):
    d = device.describe(ctx)
    assert set(d) == {"vendor", "renderer", "version", "family"}
    assert d["renderer"] == ctx.info["GL_RENDERER"] and d["version"] == ctx.info["GL_VERSION"]
    if "llvmpipe" not in d["renderer"]:
        pytest.skip(f"GL here is {d['renderer']}, not Mesa llvmpipe")
    assert d["family"] == "llvmpipe"


@pytest.mark.parametrize("vendor, renderer, family", [
    ("Mesa/X.org", "llvmpipe (LLVM 15.0.6, 256 bits)", "llvmpipe"),
    ("NVIDIA Corporation", "NVIDIA H100 80GB HBM3/PCIe/SSE2", "nvidia"),
    ("Mesa", "zink Vulkan 1.3(NVIDIA H100 (NVIDIA_PROPRIETARY))", "zink"),
    ("AMD", "AMD Radeon RX 7900 XTX (radeonsi, navi31, LLVM 17.0.6, DRM 3.57)", "amd"),
    ("ATI Technologies Inc.", "Radeon RX 580", "amd"),
    ("Intel", "Mesa Intel(R) UHD Graphics 630 (CFL GT2)", "intel"),
    ("nouveau", "NV134", "nv134"),
])
def test_describe_family(vendor, renderer, family):
    ctx = types.SimpleNamespace(info={"GL_VENDOR": vendor, "GL_RENDERER": renderer, "GL_VERSION": "4.6"})
    assert device.describe(ctx) == {"vendor": vendor, "renderer": renderer, "version": "4.6", "family": family}


@pytest.fixture
def fake_nvml(monkeypatch):
    """Installs a fake pynvml module (and forgets the cached real one, before and after)."""
    device._nvml.cache_clear()

    def install(module):
        monkeypatch.setitem(sys.modules, "pynvml", module)

    yield install
    device._nvml.cache_clear()


def test_nvml_absent(monkeypatch, fake_nvml):
    monkeypatch.setitem(sys.modules, "pynvml", None)  # import pynvml raises ImportError
    assert device.nvml_clocks() is None


def _module(**attrs):
    class NVMLError(Exception):
        pass

    return types.SimpleNamespace(**{"NVMLError": NVMLError, "NVML_CLOCK_SM": 1, "NVML_CLOCK_MEM": 2,
                                    "nvmlInit": lambda: None, **attrs})


def test_nvml_init_fails(fake_nvml):
    m = _module()

    def init():
        raise m.NVMLError("Driver Not Loaded")

    m.nvmlInit = init
    fake_nvml(m)
    assert device.nvml_clocks() is None


def test_nvml_query_fails(fake_nvml):
    m = _module(nvmlSystemGetDriverVersion=lambda: "580.1")

    def count():
        raise m.NVMLError("GPU is lost")

    m.nvmlDeviceGetCount = count
    fake_nvml(m)
    assert device.nvml_clocks() is None


def test_nvml_values(fake_nvml):
    calls = []

    def init():
        calls.append("init")

    clocks = {(0, 1): 1980, (0, 2): 2619, (1, 1): 345, (1, 2): 1593}
    fake_nvml(_module(
        nvmlInit=init,
        nvmlSystemGetDriverVersion=lambda: b"580.95.05",
        nvmlDeviceGetCount=lambda: 2,
        nvmlDeviceGetHandleByIndex=lambda i: i,
        nvmlDeviceGetName=lambda h: [b"NVIDIA H100 80GB HBM3", "NVIDIA H200"][h],
        nvmlDeviceGetPciInfo=lambda h: types.SimpleNamespace(busId=f"00000000:{h + 0x18:02X}:00.0".encode()),
        nvmlDeviceGetClockInfo=lambda h, kind: clocks[h, kind],
        nvmlDeviceGetMaxClockInfo=lambda h, kind: 1980,
        # no nvmlDeviceGetCurrentClocksEventReasons: the older throttle-reasons call is used
        nvmlDeviceGetCurrentClocksThrottleReasons=lambda h: [0, 0x1 | 0x4 | 0x1000][h],
        nvmlDeviceGetUtilizationRates=lambda h: types.SimpleNamespace(gpu=[97, 0][h], memory=40)))
    expected = {"driver": "580.95.05", "gpus": [
        {"index": 0, "name": "NVIDIA H100 80GB HBM3", "pci_bus_id": "00000000:18:00.0", "sm_clock_mhz": 1980,
         "sm_clock_max_mhz": 1980, "mem_clock_mhz": 2619, "clock_reasons": [], "util_pct": 97},
        {"index": 1, "name": "NVIDIA H200", "pci_bus_id": "00000000:19:00.0", "sm_clock_mhz": 345,
         "sm_clock_max_mhz": 1980, "mem_clock_mhz": 1593, "clock_reasons": ["gpu_idle", "sw_power_cap", "0x1000"],
         "util_pct": 0}]}
    assert device.nvml_clocks() == expected
    assert device.nvml_clocks() == expected
    assert calls == ["init"]  # NVML is started once per process, not per call


def test_nvml_here():
    """This project does not depend on nvidia-ml-py: without it (or without NVIDIA's driver) no clocks and
    no error; with both, every GPU's clocks."""
    device._nvml.cache_clear()
    clocks = device.nvml_clocks()
    try:
        import pynvml

        pynvml.nvmlInit()
    except Exception:
        assert clocks is None
        return
    assert clocks["gpus"] and [g["index"] for g in clocks["gpus"]] == list(range(len(clocks["gpus"])))
    assert set(clocks["gpus"][0]) == {"index", "name", "pci_bus_id", "sm_clock_mhz", "sm_clock_max_mhz",
                                      "mem_clock_mhz", "clock_reasons", "util_pct"}
    assert 0 < clocks["gpus"][0]["sm_clock_mhz"] <= clocks["gpus"][0]["sm_clock_max_mhz"]
