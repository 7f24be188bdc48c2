"""Type stubs of lensbake's native module (units: mm, nm, degrees; see `lensbake`)."""

from os import PathLike
from typing import Any, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

OUTCOME_OK: int
OUTCOME_VIGNETTED: int
OUTCOME_TIR: int
OUTCOME_MISSED: int
LOOKUP_PASSES: int
LOOKUP_BLOCKED: int
LOOKUP_OUTSIDE: int

_Path = Union[str, PathLike[str]]
_Rows = npt.ArrayLike  # n x 3, converted to float64

# Lens.trace's results, and its `out`: end positions and directions (n x 3 float64), outcome
# codes (uint8) and the surfaces the outcomes happened at (uint32).
_TraceArrays = Tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.uint8],
    npt.NDArray[np.uint32],
]

class LensbakeError(ValueError):
    """A lens, a table or an argument lensbake refuses; the message is the command line's."""

class Lens:
    """A lens loaded and validated (`load_lens`)."""

    @property
    def name(self) -> str: ...
    @property
    def title(self) -> str: ...
    @property
    def design_wavelength_nm(self) -> float: ...
    @property
    def surfaces(self) -> list[dict[str, Any]]: ...
    @property
    def conditions(self) -> dict[str, Any]: ...
    def convert(self, path: _Path) -> None: ...
    def analyze(
        self,
        *,
        wavelength_nm: Optional[float] = None,
        field_deg: Optional[float] = None,
        epd_mm: Optional[float] = None,
        object_distance_mm: Optional[float] = None,
        find_stop: bool = False,
        ray_aiming: Optional[str] = None,
    ) -> dict[str, Any]: ...
    def trace(
        self,
        origins: _Rows,
        directions: _Rows,
        wavelength_nm: Optional[float] = None,
        *,
        apertures: bool = True,
        backward: bool = False,
        out: Optional[_TraceArrays] = None,
    ) -> _TraceArrays: ...
    # The wave options of wavefront, mtf and psf: field_deg, wavelengths_nm, weights, f_number,
    # epd_mm, object_distance_mm, ray_aiming, samples, grid, defocus_mm (help(lensbake.Lens)).
    def wavefront(self, **options: Any) -> dict[str, Any]: ...
    def mtf(
        self, frequencies_per_mm: Optional[Sequence[float]] = None, **options: Any
    ) -> dict[str, Any]: ...
    def psf(self, **options: Any) -> Tuple[npt.NDArray[np.float64], Tuple[float, float]]: ...

class Table:
    """A baked lens ray transfer function table (`bake`, `Table.read`)."""

    @property
    def resolution(self) -> Tuple[int, int, int]: ...
    @property
    def wavelengths_nm(self) -> list[float]: ...
    @property
    def f_number(self) -> float: ...
    def film_z(self, focus_mm: Optional[float] = None) -> float: ...
    def lookup(
        self,
        origins: _Rows,
        directions: _Rows,
        *,
        focus_mm: Optional[float] = None,
        f_number: Optional[float] = None,
        layer: int = 0,
    ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.uint8]]: ...
    def write(self, path: _Path) -> None: ...
    @staticmethod
    def read(path: _Path, lens: Optional[Lens] = None) -> Table: ...

def load_lens(path_or_name: str, format: Optional[str] = None) -> Lens: ...
def bake(
    lens: Lens,
    resolution: int = 32,
    *,
    f_number: Optional[float] = None,
    focus_mm: Optional[float] = None,
    focus_near_mm: Optional[float] = None,
    wavelengths_nm: Optional[Sequence[float]] = None,
    precision: str = "f32",
) -> Table: ...
def render(
    lens: Lens,
    *,
    model: str = "traced",
    width: int = 160,
    height: int = 120,
    samples_per_pixel: int = 8,
    f_number: Optional[float] = None,
    focus_mm: Optional[float] = None,
    table_dir: Optional[_Path] = None,
    seed: int = 1,
) -> npt.NDArray[np.float32]: ...
def tradeoff(
    lens: Lens,
    budget_px: float,
    *,
    focus_mm: Optional[float] = None,
    nearest_mm: Optional[float] = None,
    f_number: Optional[float] = None,
    film_fraction: float = 1.0,
    pixels: float = 1920.0,
    monochrome: bool = False,
) -> dict[str, Any]: ...
