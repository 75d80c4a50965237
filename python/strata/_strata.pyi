# Type stubs for the compiled module (python/strata_module.cpp).
import os
from typing import Any, Callable, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, "os.PathLike[str]"]

class Error(RuntimeError): ...

def bake(
    high: _Path,
    control: _Path,
    out: _Path,
    *,
    tolerance: Union[float, str] = ...,
    control_faces: int = ...,
    uv: str = ...,
    size: Union[int, str] = ...,
    scheme: str = ...,
    overlap: str = ...,
    threads: int = ...,
    error_levels: Union[Tuple[int, int], int, str] = ...,
    skeleton: _Path = ...,
    map_coding: str = ...,
    mesh_coding: str = ...,
    compress: bool = ...,
    exr: bool = ...,
    float_exr: bool = ...,
    png: int = ...,
    layers: bool = ...,
    close_holes: bool = ...,
    fit: bool = ...,
    max_memory: int = ...,
    report: _Path = ...,
    progress: Optional[Callable[[str, float], Any]] = ...,
) -> dict[str, Any]: ...

class Rig:
    @property
    def path(self) -> str: ...
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def animations(self) -> list[str]: ...
    @property
    def recommended_level(self) -> int: ...
    @property
    def scheme(self) -> str: ...
    @property
    def shading(self) -> str: ...
    @property
    def control_vertex_count(self) -> int: ...
    @property
    def warnings(self) -> list[str]: ...
    def reconstruct(
        self,
        level: Optional[int] = None,
        animation: Optional[str] = None,
        time: Optional[float] = None,
        displacement: bool = True,
        view: Optional[Tuple[Sequence[float], Sequence[float], float, float]] = None,
        pixel_error: float = 1.0,
    ) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.uint32]]: ...

def bake_options() -> list[dict[str, Any]]: ...

def load_rig(path: _Path) -> Rig: ...
