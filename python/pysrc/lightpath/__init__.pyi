"""lightpath: a GPU renderer on Vulkan (path tracing, BDPT and MMLT), from Python."""
from os import PathLike
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

ImageLike = Union["RenderResult", npt.NDArray[np.float32], str, "PathLike[str]"]

class SceneError(ValueError):
    """A scene file that cannot be read; the message names the file and line."""

class RenderError(RuntimeError):
    """A render that failed on the device (the message names the stage), or no device."""

class Scene:
    """A scene read from a .test or .pbrt file, with the settings the command line can
    override. Setting an attribute checks it (ValueError) and changes only this Scene."""

    size: Tuple[int, int]
    """The image size, (width, height)."""
    max_depth: int
    """Scattering vertices per path at most; -1: unbounded, with Russian roulette."""
    spp: int
    """Samples per pixel (mmlt: mutations per pixel)."""
    integrator: str
    """pathtracer, direct, analyticdirect, bdpt or mmlt."""
    @property
    def path(self) -> str:
        """The file the scene was read from."""

class RenderResult:
    """A render: its image, how it was made, and what its integrator measured."""

    @property
    def image(self) -> npt.NDArray[np.float32]:
        """The image, shape (height, width, 3), linear RGB (a new array at each access)."""
    @property
    def metadata(self) -> Dict[str, Any]:
        """What the EXR header records: integrator, samples_per_pixel, seeds, max_depth,
        backend, device, render_seconds, version, scene_file, scene_sha256; and
        interrupted."""
    @property
    def gbuffer(self) -> Optional[Dict[str, npt.NDArray[np.float32]]]:
        """A pbrt `Film "gbuffer"` scene: {channel: array of shape (height, width)} for
        Albedo.R/G/B, P.X/Y/Z, N.X/Y/Z, Ns.X/Y/Z, u and v (pbrt-v4's names; camera space
        unless the film's coordinatesystem is "world"); None for other films. save()
        writes them into the EXR beside R, G, B."""
    @property
    def interrupted(self) -> bool:
        """Stopped early (Ctrl-C or interrupt()): the image is the mean of the samples done."""
    @property
    def strategies(
        self,
    ) -> Optional[Dict[Tuple[int, int], Tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]]]:
        """bdpt with strategies=True: {(s, t): (weighted, unweighted)}, s light vertices
        and t camera vertices; the weighted images sum to the image."""
    @property
    def depths(self) -> Optional[Dict[int, npt.NDArray[np.float32]]]:
        """mmlt with depths=True: {scattering vertices: image}; they sum to the image
        (less the bdpt tail of max_depth -1)."""
    @property
    def mmlt(self) -> Optional[Dict[str, Any]]:
        """mmlt's statistics: b, b_stderr, chains, mutations, bootstrap_samples,
        bootstrap_seconds, chain_seconds, mutations_per_second, and depths (a list of
        {depth, b, chains, large_acceptance, small_acceptance})."""
    @property
    def trace(self) -> List[Dict[str, Any]]:
        """The per-stage trace: {name, gpu, start_us, dur_us} for each CPU stage and GPU
        dispatch, as --trace writes it; host stages add host_bytes and host_peak_bytes,
        the scene upload device_bytes and data ({kind: {bytes, chunks}} for each kind of
        scene data read by address)."""
    def save(self, path: Union[str, "PathLike[str]"]) -> None:
        """Write the image: .exr (linear float, with the metadata) or .png (8-bit, with
        the scene's gamma), through a temporary file and a rename."""

def load(path: Union[str, "PathLike[str]"]) -> Scene:
    """Read a scene file (.test, or .pbrt by its extension). Raises SceneError naming
    the file and line of what is wrong."""

def render(
    scene: Scene,
    integrator: Optional[str] = None,
    spp: Optional[int] = None,
    seed: int = 0,
    accel: str = "auto",
    time_limit: Optional[float] = None,
    device: Optional[str] = None,
    progress: bool = False,
    max_depth: Optional[int] = None,
    size: Optional[Tuple[int, int]] = None,
    strategies: bool = False,
    depths: bool = False,
    mmlt_bootstrap: Optional[int] = None,
    mmlt_chains: Optional[int] = None,
    mmlt_sigma: Optional[float] = None,
    mmlt_large_step: Optional[float] = None,
) -> RenderResult:
    """Render a copy of `scene`; the arguments override its settings as the command
    line's options do (accel: auto, rayquery, bvh, cwbvh or bvh2; device: an index or
    part of a name; time_limit: stop after about this many seconds). Bad arguments raise
    ValueError before anything renders. The GIL is released while the device works; the
    device and its pipelines are opened once per process. Ctrl-C stops the render after
    the dispatch in flight and returns the image so far (interrupted=True); a second
    Ctrl-C raises KeyboardInterrupt at once."""

def interrupt() -> None:
    """Stop every render under way (from any thread), as Ctrl-C does."""

def devices() -> List[Dict[str, Any]]:
    """The Vulkan devices: index, name, kind, driver, api_version, ray_query,
    float_atomics, max_storage_buffer_range, max_workgroup_invocations, timestamps, and
    default (the one render picks when device is None)."""

def compare(a: ImageLike, b: ImageLike) -> Dict[str, Any]:
    """Image a against reference b, as `lightpath compare`: mean_a, mean_b (per
    channel), rmse, relmse (epsilon 0.01)."""

def merge(renders: List[Union[RenderResult, str, "PathLike[str]"]]) -> RenderResult:
    """Average renders of the same scene and settings made with different seeds,
    weighted by samples per pixel, as `lightpath merge`; ValueError for renders that do
    not belong together."""

def read(path: Union[str, "PathLike[str]"]) -> RenderResult:
    """Read an EXR (with its lightpath metadata, when it has some)."""
