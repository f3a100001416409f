"""lightpath: a GPU renderer on Vulkan (path tracing, BDPT and MMLT), from Python.

    import lightpath as lp
    scene = lp.load("scenes/cornell-slab.test")
    r = lp.render(scene, integrator="bdpt", spp=64, seed=1)
    r.image            # float32 array (height, width, 3), linear RGB

See docs/python.md. The renderer is the same Rust library the command line runs: a
render here is bit for bit the command line's for the same scene, settings and seed.
"""
from ._lightpath import (
    RenderError,
    RenderResult,
    Scene,
    SceneError,
    __version__,
    compare,
    devices,
    interrupt,
    load,
    merge,
    read,
    render,
)

__all__ = [
    "RenderError",
    "RenderResult",
    "Scene",
    "SceneError",
    "__version__",
    "compare",
    "devices",
    "interrupt",
    "load",
    "merge",
    "read",
    "render",
]
