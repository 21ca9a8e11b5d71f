# Types of the extension module (src/*.rs), for editors and type checkers.
from os import PathLike
from typing import Any, Dict, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, PathLike]
_Points = npt.ArrayLike

__version__: str

class MemaError(ValueError): ...

class Entities:
    centres: npt.NDArray[np.float64]
    semi_axes: npt.NDArray[np.float64]
    rotations: npt.NDArray[np.float64]
    quaternions: npt.NDArray[np.float64]
    weights: npt.NDArray[np.float64]
    kinds: npt.NDArray[np.str_]
    def __len__(self) -> int: ...

class Map:
    def __init__(self, data: bytes) -> None: ...
    def __len__(self) -> int: ...
    def save(self, path: _Path) -> None: ...
    def to_bytes(self, format: str = "mema") -> bytes: ...
    @property
    def origin(self) -> npt.NDArray[np.float64]: ...
    @property
    def quantized(self) -> bool: ...
    @property
    def report(self) -> Optional[Dict[str, Any]]: ...
    @property
    def labels(self) -> Optional[npt.NDArray[np.int64]]: ...
    @property
    def entities(self) -> Entities: ...
    def eval(
        self,
        cloud: Union[_Path, _Points],
        samples: int = 200000,
        seed: int = 0,
        units: Optional[str] = None,
    ) -> Dict[str, Any]: ...
    def nearest(self, points: _Points) -> Tuple[Any, Any]: ...
    def occupied(self, points: _Points) -> Any: ...
    def ray_cast(
        self, origins: _Points, directions: _Points, max_range: float = 1e6
    ) -> Tuple[Any, Any, Any]: ...
    def transform(
        self, rotation: Optional[_Points] = None, translation: Optional[_Points] = None
    ) -> "Map": ...

def _read_cloud(
    path: _Path,
    units: Optional[str] = None,
    topic: Optional[str] = None,
    frame: Optional[str] = None,
    classes: Optional[str] = None,
) -> Tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float32],
    npt.NDArray[np.float64],
    str,
    int,
    Tuple[int, int, int],
]: ...
def map(
    points: _Points,
    k: Optional[int] = None,
    bytes: Optional[int] = None,
    seed: int = 0,
    paper: bool = False,
    *,
    model: str = "shells",
    tangent_scale: float = 2.0,
    normal_scale: float = 0.7,
    surface_rounds: int = 30,
    tolerance: Optional[float] = None,
    capacity: int = 16384,
    voronoi_rounds: int = 0,
    entity: str = "ellipsoid",
    alpha: float = 0.8,
    threshold: float = 4.0,
    sphere_tolerance: float = 0.01,
    bounds: str = "spread",
    out_of_bounds: str = "clamp",
    volume: str = "exact",
    init: str = "seeded",
    generations: int = 50,
    max_iterations: int = 100,
    crop: Optional[Sequence[float]] = None,
    voxel: Optional[float] = None,
    stream: bool = False,
    working: Optional[int] = None,
) -> Map: ...
def load(path: _Path) -> Map: ...
def from_bytes(data: bytes) -> Map: ...
def rotation_degrees(angles: Sequence[float]) -> npt.NDArray[np.float64]: ...
