"""Occupancy-grid maps of the cave: generated from a seed or loaded from a file.

Cells are ``(row, col)``. Metric points are ``(x, y)`` with ``x`` along columns and ``y``
along rows (image convention, y grows downwards); a cell's point is its centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from btcap.errors import BtcapError
from btcap.sim.world.distance import Cell, CellLike, as_cell, distance_field

__all__ = ["GridMap", "MapError"]

_FOUR_CONNECTED = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=np.bool_)
_TEXT_CHARS = "#.SD"
_SUFFIXES = (".npy", ".png", ".txt")


class MapError(BtcapError, ValueError):
    """A map that cannot be used; the message starts with its source (usually the file)."""


@dataclass(frozen=True, eq=False)
class GridMap:
    """A connected cave: where robots can drive, where they start, where objects go.

    Construction validates everything (shape, free start and decontamination area, both
    in one 4-connected component) so that the simulation never has to. ``reachable`` is
    the component of the start: cells elsewhere exist on the map but no robot gets there.
    """

    free: NDArray[np.bool_] = field(repr=False)
    start: Cell
    decon_area: Cell
    cell_size_m: float = 1.0
    source: str = "<array>"
    reachable: NDArray[np.bool_] = field(init=False, repr=False)
    _reachable_cells: NDArray[np.intp] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        where = self.source
        free = np.asarray(self.free)
        if free.ndim != 2 or free.dtype != np.bool_:
            raise MapError(f"{where}: expected a 2-D bool grid, got {free.dtype} {free.shape}")
        if free.size == 0:
            raise MapError(f"{where}: empty map (expected at least one row and column)")
        if not free.any():
            raise MapError(f"{where}: no free cell (expected at least one traversable cell)")
        if not (math.isfinite(self.cell_size_m) and self.cell_size_m > 0):
            raise MapError(f"{where}: cell size must be a positive number of metres")
        free = free.copy()
        free.flags.writeable = False
        start = _checked_cell(free, self.start, "start", where)
        decon = _checked_cell(free, self.decon_area, "decon area", where)
        labels = _components(free)
        if labels[decon] != labels[start]:
            raise MapError(f"{where}: decon area {decon} is not reachable from start {start}")
        reachable = labels == labels[start]
        reachable.flags.writeable = False
        cells = np.argwhere(reachable)
        cells.flags.writeable = False
        for name, value in (
            ("free", free),
            ("start", start),
            ("decon_area", decon),
            ("cell_size_m", float(self.cell_size_m)),
            ("reachable", reachable),
            ("_reachable_cells", cells),
        ):
            object.__setattr__(self, name, value)

    def __repr__(self) -> str:
        return (
            f"GridMap({self.height}x{self.width}, cell_size_m={self.cell_size_m}, "
            f"start={self.start}, decon_area={self.decon_area}, source={self.source!r})"
        )

    # -- construction -------------------------------------------------------------------

    @classmethod
    def from_array(
        cls,
        free: ArrayLike,
        *,
        start: CellLike | None = None,
        decon_area: CellLike | None = None,
        cell_size_m: float = 1.0,
        source: str = "<array>",
    ) -> GridMap:
        """A map from a bool grid, placing a missing start / decon area far apart."""
        grid = np.asarray(free)
        if grid.ndim != 2:
            raise MapError(f"{source}: expected a 2-D grid, got shape {grid.shape}")
        if grid.dtype != np.bool_:
            grid = _bool_grid(grid, source)
        if grid.size and grid.any():
            start_cell, decon_cell = _place_endpoints(grid, start, decon_area, source)
        else:
            start_cell = decon_cell = (0, 0)  # the constructor reports the real problem
        return cls(grid, start_cell, decon_cell, cell_size_m, source)

    @classmethod
    def generate_cave(
        cls,
        width: int,
        height: int,
        *,
        seed: int,
        fill: float = 0.45,
        iterations: int = 5,
        cell_size_m: float = 1.0,
    ) -> GridMap:
        """A cellular-automaton cave, deterministic per seed, reduced to one connected part.

        Each cell starts as wall with probability ``fill``; every iteration a cell becomes
        wall when at least 5 of the 9 cells of its 3x3 block are walls (outside counts as
        wall), which smooths noise into caverns and corridors. Start is on the left, the
        decon area is the free cell farthest from it by path.
        """
        if width < 1 or height < 1:
            raise ValueError(f"cave size must be positive, got {width}x{height}")
        if not 0.0 <= fill < 1.0:
            raise ValueError(f"fill must be in [0, 1), got {fill}")
        if iterations < 0:
            raise ValueError(f"iterations must be >= 0, got {iterations}")
        source = f"<cave {width}x{height} seed={seed}>"
        from scipy import ndimage  # deferred: importing scipy.ndimage takes ~0.5 s

        rng = np.random.default_rng(seed)
        wall = (rng.random((height, width)) < fill).astype(np.uint8)
        block = np.ones((3, 3), dtype=np.uint8)
        for _ in range(iterations):
            walls_around = ndimage.convolve(wall, block, mode="constant", cval=1)
            wall = (walls_around >= 5).astype(np.uint8)
        free = wall == 0
        labels = _components(free)
        if labels.max() == 0:
            raise MapError(f"{source}: no free cell (fill {fill} is too high)")
        sizes = np.bincount(labels.ravel())
        sizes[0] = 0
        return cls.from_array(labels == int(sizes.argmax()), cell_size_m=cell_size_m, source=source)

    @classmethod
    def load(cls, path: str | Path, *, cell_size_m: float = 1.0) -> GridMap:
        """A map from ``.npy`` (bool or 0/1), ``.png`` (dark = wall) or ``.txt`` (``#.SD``)."""
        file = Path(path)
        suffix = file.suffix.lower()
        if suffix not in _SUFFIXES:
            raise MapError(
                f"{file}: unsupported map format {suffix or '(none)'!r} "
                f"(expected one of {', '.join(_SUFFIXES)})"
            )
        if not file.is_file():
            raise MapError(f"{file}: no such map file (expected an existing {suffix} file)")
        start: Cell | None = None
        decon: Cell | None = None
        if suffix == ".npy":
            free = _read_npy(file)
        elif suffix == ".png":
            free = _read_png(file)
        else:
            free, start, decon = _read_txt(file)
        return cls.from_array(
            free, start=start, decon_area=decon, cell_size_m=cell_size_m, source=str(file)
        )

    def save(self, path: str | Path) -> Path:
        """Write ``.npy`` (grid only), ``.txt`` (with ``S`` and ``D``) or ``.png``."""
        file = Path(path)
        suffix = file.suffix.lower()
        if suffix == ".npy":
            np.save(file, self.free)
        elif suffix == ".txt":
            chars = np.where(self.free, ".", "#")
            chars[self.start] = "S"
            chars[self.decon_area] = "D"
            file.write_text("".join("".join(row) + "\n" for row in chars), encoding="utf-8")
        elif suffix == ".png":
            from matplotlib import image

            image.imsave(file, self.free.astype(np.uint8), cmap="gray", vmin=0, vmax=1)
        else:
            raise MapError(
                f"{file}: unsupported map format {suffix or '(none)'!r} "
                f"(expected one of {', '.join(_SUFFIXES)})"
            )
        return file

    # -- queries ------------------------------------------------------------------------

    @property
    def height(self) -> int:
        return int(self.free.shape[0])

    @property
    def width(self) -> int:
        return int(self.free.shape[1])

    @property
    def shape(self) -> tuple[int, int]:
        return self.height, self.width

    def to_metres(self, cells: ArrayLike) -> NDArray[np.float64]:
        """Cell centres ``(..., 2)`` as ``(x, y)`` metres, for radii and plots."""
        rc = np.asarray(cells, dtype=np.float64)
        if rc.shape[-1:] != (2,):
            raise ValueError(f"cells must have shape (..., 2), got {rc.shape}")
        return np.stack(
            ((rc[..., 1] + 0.5) * self.cell_size_m, (rc[..., 0] + 0.5) * self.cell_size_m), axis=-1
        )

    def to_cell(self, points: ArrayLike) -> NDArray[np.int64]:
        """The ``(row, col)`` cells containing ``(x, y)`` metric points (may lie off the map)."""
        xy = np.asarray(points, dtype=np.float64)
        if xy.shape[-1:] != (2,):
            raise ValueError(f"points must have shape (..., 2), got {xy.shape}")
        scaled = np.floor(xy / self.cell_size_m).astype(np.int64)
        return np.stack((scaled[..., 1], scaled[..., 0]), axis=-1)

    def in_bounds(self, cell: CellLike) -> bool:
        row, col = as_cell(cell)
        return 0 <= row < self.height and 0 <= col < self.width

    def is_free(self, cell: CellLike) -> bool:
        """Whether a robot may stand on ``cell`` (off-map cells are not free)."""
        row, col = as_cell(cell)
        return self.in_bounds((row, col)) and bool(self.free[row, col])

    def random_free_cells(
        self, n: int, rng: np.random.Generator, *, replace: bool = False
    ) -> NDArray[np.intp]:
        """``n`` random reachable cells ``(n, 2)``: spawn points, objects, goals."""
        cells = self._reachable_cells
        if not replace and n > len(cells):
            raise ValueError(f"asked for {n} distinct cells, the map has {len(cells)}")
        picked: NDArray[np.intp] = cells[rng.choice(len(cells), size=n, replace=replace)]
        return picked


def _components(free: NDArray[np.bool_]) -> NDArray[np.int32]:
    """Label of each cell's 4-connected free component (0 for walls)."""
    from scipy import ndimage  # deferred: importing scipy.ndimage takes ~0.5 s

    labels: NDArray[np.int32] = ndimage.label(free, structure=_FOUR_CONNECTED)[0]
    return labels


def _checked_cell(free: NDArray[np.bool_], cell: CellLike, name: str, where: str) -> Cell:
    try:
        row, col = as_cell(cell)
    except (TypeError, ValueError) as exc:
        raise MapError(f"{where}: {name} must be a (row, col) cell, got {cell!r}") from exc
    height, width = free.shape
    if not (0 <= row < height and 0 <= col < width):
        raise MapError(f"{where}: {name} {(row, col)} is outside the {height}x{width} map")
    if not free[row, col]:
        raise MapError(f"{where}: {name} {(row, col)} is a wall (expected a free cell)")
    return row, col


def _place_endpoints(
    free: NDArray[np.bool_], start: CellLike | None, decon: CellLike | None, where: str
) -> tuple[Cell, Cell]:
    """Fill in a missing start (leftmost, nearest the middle) and decon area (farthest)."""
    labels = _components(free)
    if start is not None:
        component = int(labels[_checked_cell(free, start, "start", where)])
    elif decon is not None:
        component = int(labels[_checked_cell(free, decon, "decon area", where)])
    else:
        sizes = np.bincount(labels.ravel())
        sizes[0] = 0
        component = int(sizes.argmax())
    if start is None:
        rows, cols = np.nonzero(labels == component)
        middle_gap = np.abs(2 * rows - (free.shape[0] - 1))
        best = np.lexsort((rows, middle_gap, cols))[0]
        start = (int(rows[best]), int(cols[best]))
    start_cell = as_cell(start)
    if decon is not None:
        return start_cell, as_cell(decon)
    field = distance_field(free, start_cell)
    row, col = np.unravel_index(int(np.argmax(field)), field.shape)
    return start_cell, (int(row), int(col))


def _bool_grid(grid: NDArray[Any], where: str) -> NDArray[np.bool_]:
    if grid.dtype.kind not in "biuf" or not np.isin(grid, (0, 1)).all():
        raise MapError(f"{where}: expected a bool or 0/1 grid (1 = free), got {grid.dtype} values")
    return grid.astype(np.bool_)


def _read_npy(file: Path) -> NDArray[np.bool_]:
    try:
        data = np.load(file, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise MapError(f"{file}: not a readable .npy array ({exc})") from exc
    if not isinstance(data, np.ndarray):
        raise MapError(f"{file}: expected a single .npy array, got {type(data).__name__}")
    if data.ndim != 2:
        raise MapError(f"{file}: expected a 2-D grid, got shape {data.shape}")
    return data if data.dtype == np.bool_ else _bool_grid(data, str(file))


def _read_png(file: Path) -> NDArray[np.bool_]:
    from matplotlib import image

    try:
        pixels = np.asarray(image.imread(file))
    except (OSError, ValueError, SyntaxError) as exc:
        raise MapError(f"{file}: not a readable PNG image ({exc})") from exc
    if pixels.dtype.kind in "iu":
        pixels = pixels / np.iinfo(pixels.dtype).max
    if pixels.ndim == 3:
        pixels = pixels[..., :3].mean(axis=-1) if pixels.shape[-1] >= 3 else pixels[..., 0]
    if pixels.ndim != 2:
        raise MapError(f"{file}: expected a grey or colour image, got shape {pixels.shape}")
    return np.asarray(pixels >= 0.5, dtype=np.bool_)


def _read_txt(file: Path) -> tuple[NDArray[np.bool_], Cell | None, Cell | None]:
    try:
        lines = file.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise MapError(f"{file}: not a readable text map ({exc})") from exc
    while lines and not lines[-1].strip():
        lines.pop()
    expected = "rows of '#' (wall), '.' (free), 'S' (start), 'D' (decon area)"
    if not lines or not lines[0]:
        raise MapError(f"{file}: empty map (expected {expected})")
    width = len(lines[0])
    for number, line in enumerate(lines, start=1):
        if len(line) != width:
            raise MapError(
                f"{file}: line {number} has {len(line)} columns, expected {width} "
                "like line 1 (maps are rectangular)"
            )
    chars = np.array([list(line) for line in lines], dtype="<U1")
    unknown = np.argwhere(~np.isin(chars, list(_TEXT_CHARS)))
    if len(unknown):
        row, col = (int(v) for v in unknown[0])
        raise MapError(
            f"{file}: unknown character {lines[row][col]!r} at line {row + 1}, col {col + 1} "
            f"(expected {expected})"
        )
    marks: list[Cell | None] = []
    for mark, name in (("S", "start"), ("D", "decon area")):
        found = np.argwhere(chars == mark)
        if len(found) > 1:
            places = " and ".join(f"line {r + 1}, col {c + 1}" for r, c in found[:2])
            raise MapError(f"{file}: more than one {mark!r} ({name}) at {places}")
        marks.append(as_cell(found[0]) if len(found) else None)
    return chars != "#", marks[0], marks[1]
