"""Type stubs of the strata extension module (python/strata_module.cpp documents each call)."""
from typing import Any, Optional, Sequence, Tuple, TypedDict

import numpy as np
import numpy.typing as npt

__version__: str

_Vec3 = Tuple[float, float, float]


class Error(Exception): ...
class InputError(Error, ValueError): ...
class DeviceError(Error, RuntimeError): ...
class OutOfMemoryError(Error, MemoryError): ...


class _MethodInfo(TypedDict):
    name: str
    summary: str
    exact: bool
    opencl: bool
    takes_k: bool
    translucency: bool


class _DeviceInfo(TypedDict):
    index: int
    name: str
    platform: str
    driver: str
    gpu: bool


class _NaturalView(TypedDict):
    az: float
    el: float
    distance: Optional[float]
    ortho: bool
    ortho_height: Optional[float]


class _PickedObject(TypedDict):
    object: int
    name: str


def methods() -> list[_MethodInfo]: ...
def devices() -> list[_DeviceInfo]: ...


class Device:
    def __init__(self, spec: str = "", atomics: str = "auto") -> None: ...
    @property
    def label(self) -> str: ...
    @property
    def int64_atomics(self) -> bool: ...


class Geometry:
    # Made by load() and from_arrays() only.
    def __init__(self, *args: Any, **kwargs: Any) -> None: ...
    @property
    def triangle_count(self) -> int: ...
    @property
    def vertex_count(self) -> int: ...
    @property
    def source(self) -> str: ...
    @property
    def bounding_sphere(self) -> Tuple[_Vec3, float]: ...
    def natural_view(self) -> _NaturalView: ...


def load(path: str, alpha: float = -1.0) -> Geometry: ...
def from_arrays(positions: npt.ArrayLike, indices: npt.ArrayLike,
                colors: Optional[npt.ArrayLike] = None, alpha: float = -1.0) -> Geometry: ...
def save_image(path: str, image: npt.ArrayLike) -> None: ...


class _Comparison(TypedDict):
    psnr: float
    max_abs: int
    mean_abs: float
    within_1: float
    within_2: float
    pixels: int
    error: npt.NDArray[np.uint8]
    difference: npt.NDArray[np.uint8]


def compare(image: npt.ArrayLike, reference: npt.ArrayLike) -> _Comparison: ...


class Renderer:
    def __init__(self, device: Device, method: str, effect: str = "transparency", k: int = 16,
                 sigma: float = -1.0, frames: int = 1, orbit: float = 0.0,
                 batch: str = "static", sort: str = "none", atlas: str = "packed",
                 decompose: str = "strict", cache_dir: str = "", depth_complexity: bool = False,
                 octree_variant: str = "kbuffer", leaf_tris: int = 16384, octree_k: int = 32,
                 memory_budget_mb: float = 0.0, tile_kernels: str = "auto",
                 background: Optional[_Vec3] = None, wboit_weight: str = "eq10") -> None: ...
    def set_geometry(self, geometry: Geometry) -> None: ...
    def render(self, *, az: Optional[float] = None, el: Optional[float] = None,
               width: int = 512, height: int = 512, distance: Optional[float] = None,
               ortho: Optional[bool] = None, fov: float = 40.0,
               ortho_height: Optional[float] = None, eye: Optional[_Vec3] = None,
               target: Optional[_Vec3] = None,
               up: _Vec3 = (0.0, 1.0, 0.0)) -> npt.NDArray[np.uint8]: ...
    @property
    def stats(self) -> Any: ...
    @property
    def depth_complexity(self) -> Optional[npt.NDArray[np.uint32]]: ...
    @property
    def method(self) -> _MethodInfo: ...
    @property
    def geometry(self) -> Optional[Geometry]: ...


class Picker:
    def __init__(self, device: Device) -> None: ...
    def set_geometry(self, geometry: Geometry) -> None: ...
    def pick(self, pixels: Sequence[Tuple[int, int]], all_layers: bool = False, *,
             az: Optional[float] = None, el: Optional[float] = None, width: int = 512,
             height: int = 512, distance: Optional[float] = None, ortho: Optional[bool] = None,
             fov: float = 40.0, ortho_height: Optional[float] = None,
             eye: Optional[_Vec3] = None, target: Optional[_Vec3] = None,
             up: _Vec3 = (0.0, 1.0, 0.0)) -> list[dict[str, Any]]: ...
    def objects_in_rect(self, rect: Tuple[int, int, int, int], *, az: Optional[float] = None,
                        el: Optional[float] = None, width: int = 512, height: int = 512,
                        distance: Optional[float] = None, ortho: Optional[bool] = None,
                        fov: float = 40.0, ortho_height: Optional[float] = None,
                        eye: Optional[_Vec3] = None, target: Optional[_Vec3] = None,
                        up: _Vec3 = (0.0, 1.0, 0.0)) -> list[_PickedObject]: ...
    @property
    def geometry(self) -> Optional[Geometry]: ...
