"""Grid maps: generated caves, file formats, and errors that name the file."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from btcap.sim import GridMap, MapError, distance_field

FOUR = ndimage.generate_binary_structure(2, 1)


def components(free: np.ndarray) -> int:
    return int(ndimage.label(free, structure=FOUR)[1])


# -- generated caves -----------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_cave_is_one_connected_component(seed: int) -> None:
    grid = GridMap.generate_cave(60, 40, seed=seed)
    assert grid.shape == (40, 60)
    assert components(grid.free) == 1
    assert grid.free.mean() > 0.3
    np.testing.assert_array_equal(grid.reachable, grid.free)
    assert grid.is_free(grid.start)
    assert grid.is_free(grid.decon_area)


def test_cave_places_start_left_and_decon_area_farthest_away() -> None:
    grid = GridMap.generate_cave(120, 80, seed=5)
    cols = np.nonzero(grid.free)[1]
    assert grid.start[1] == cols.min()
    field = distance_field(grid.free, grid.start)
    assert field[grid.decon_area] == field.max()
    assert field[grid.decon_area] > 100


def test_cave_is_deterministic_per_seed() -> None:
    a = GridMap.generate_cave(50, 30, seed=11)
    b = GridMap.generate_cave(50, 30, seed=11)
    c = GridMap.generate_cave(50, 30, seed=12)
    np.testing.assert_array_equal(a.free, b.free)
    assert (a.start, a.decon_area) == (b.start, b.decon_area)
    assert not np.array_equal(a.free, c.free)


def test_cave_keeps_cell_size() -> None:
    grid = GridMap.generate_cave(30, 20, seed=0, cell_size_m=0.5)
    assert grid.cell_size_m == 0.5


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"width": 0, "height": 5}, "size"),
        ({"width": 5, "height": 5, "fill": 1.0}, "fill"),
        ({"width": 5, "height": 5, "iterations": -1}, "iterations"),
    ],
)
def test_cave_parameters_are_checked(kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        GridMap.generate_cave(seed=0, **kwargs)  # type: ignore[arg-type]


def test_grid_is_read_only() -> None:
    grid = GridMap.generate_cave(20, 20, seed=0)
    with pytest.raises(ValueError, match="read-only"):
        grid.free[0, 0] = True
    assert "20x20" in repr(grid)


# -- helpers -------------------------------------------------------------------------------


def test_metres_and_cells_convert_both_ways() -> None:
    grid = GridMap.from_array(np.ones((4, 6), dtype=bool), cell_size_m=0.5)
    np.testing.assert_array_equal(grid.to_metres((1, 2)), [1.25, 0.75])
    cells = np.array([[0, 0], [3, 5], [2, 1]])
    np.testing.assert_array_equal(grid.to_cell(grid.to_metres(cells)), cells)
    np.testing.assert_array_equal(grid.to_cell([[0.49, 1.99]]), [[3, 0]])
    with pytest.raises(ValueError, match=r"\(\.\.\., 2\)"):
        grid.to_metres([1, 2, 3])
    with pytest.raises(ValueError, match=r"\(\.\.\., 2\)"):
        grid.to_cell([1.0])


def test_is_free_handles_walls_and_off_map_cells() -> None:
    grid = GridMap.from_array(np.array([[1, 0], [1, 1]], dtype=bool))
    assert grid.is_free((0, 0))
    assert not grid.is_free((0, 1))
    assert not grid.is_free((-1, 0))
    assert not grid.is_free((2, 0))


def test_random_free_cells_are_distinct_reachable_and_seeded() -> None:
    grid = GridMap.generate_cave(40, 30, seed=2)
    cells = grid.random_free_cells(50, np.random.default_rng(9))
    assert cells.shape == (50, 2)
    assert len({tuple(c) for c in cells}) == 50
    assert grid.reachable[cells[:, 0], cells[:, 1]].all()
    np.testing.assert_array_equal(cells, grid.random_free_cells(50, np.random.default_rng(9)))
    many = grid.random_free_cells(5000, np.random.default_rng(1), replace=True)
    assert grid.free[many[:, 0], many[:, 1]].all()
    with pytest.raises(ValueError, match="distinct"):
        grid.random_free_cells(10**6, np.random.default_rng(0))


def test_from_array_keeps_only_the_start_component_reachable() -> None:
    free = np.array([[1, 1, 0, 1], [1, 1, 0, 1]], dtype=bool)
    grid = GridMap.from_array(free, start=(0, 3))
    assert grid.decon_area == (1, 3)
    np.testing.assert_array_equal(grid.reachable, [[0, 0, 0, 1], [0, 0, 0, 1]])
    cells = grid.random_free_cells(2, np.random.default_rng(0))
    assert set(map(tuple, cells.tolist())) == {(0, 3), (1, 3)}


@pytest.mark.parametrize(
    ("start", "decon", "message"),
    [
        ((0, 2), None, "start .* wall"),
        ((9, 0), None, "outside"),
        ((0, 0), (0, 3), "not reachable"),
    ],
)
def test_from_array_rejects_bad_endpoints(
    start: tuple[int, int], decon: tuple[int, int] | None, message: str
) -> None:
    free = np.array([[1, 1, 0, 1]], dtype=bool)
    with pytest.raises(MapError, match=message):
        GridMap.from_array(free, start=start, decon_area=decon)


# -- files ---------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".npy", ".txt", ".png"])
def test_save_load_round_trip(tmp_path: Path, suffix: str) -> None:
    grid = GridMap.generate_cave(45, 30, seed=4, cell_size_m=0.5)
    path = grid.save(tmp_path / f"cave{suffix}")
    loaded = GridMap.load(path, cell_size_m=0.5)
    np.testing.assert_array_equal(loaded.free, grid.free)
    assert (loaded.start, loaded.decon_area) == (grid.start, grid.decon_area)
    assert loaded.cell_size_m == 0.5
    assert loaded.source == str(path)


def test_text_round_trip_keeps_chosen_endpoints(tmp_path: Path) -> None:
    grid = GridMap.from_array(np.ones((3, 5), dtype=bool), start=(1, 2), decon_area=(0, 0))
    loaded = GridMap.load(grid.save(tmp_path / "m.txt"))
    assert (loaded.start, loaded.decon_area) == ((1, 2), (0, 0))
    assert (tmp_path / "m.txt").read_text() == "D....\n..S..\n.....\n"


def test_text_map_reads_marks(tmp_path: Path) -> None:
    path = tmp_path / "m.txt"
    path.write_text("#####\n#S.D#\n#...#\n#####\n\n")
    grid = GridMap.load(path)
    assert grid.shape == (4, 5)
    assert (grid.start, grid.decon_area) == ((1, 1), (1, 3))
    assert int(grid.free.sum()) == 6


def test_text_map_without_marks_places_them(tmp_path: Path) -> None:
    path = tmp_path / "m.txt"
    path.write_text("....\n.##.\n....\n")
    grid = GridMap.load(path)
    assert grid.start == (1, 0)
    assert grid.decon_area == (1, 3)


def test_npy_accepts_zero_one_integers(tmp_path: Path) -> None:
    path = tmp_path / "m.npy"
    np.save(path, np.array([[1, 1, 0], [0, 1, 1]], dtype=np.uint8))
    grid = GridMap.load(path)
    np.testing.assert_array_equal(grid.free, [[1, 1, 0], [0, 1, 1]])
    assert (grid.start, grid.decon_area) == ((0, 0), (1, 2))


def test_png_dark_pixels_are_walls(tmp_path: Path) -> None:
    from matplotlib import image

    pixels = np.ones((3, 4, 3), dtype=np.float32)
    pixels[1, 1:3] = 0.1  # dark grey
    pixels[0, 3] = (1.0, 0.0, 0.0)  # red: mean 1/3, dark
    path = tmp_path / "m.png"
    image.imsave(path, pixels)
    grid = GridMap.load(path)
    np.testing.assert_array_equal(grid.free, [[1, 1, 1, 0], [1, 0, 0, 1], [1, 1, 1, 1]])


def _write(text: str | bytes) -> Callable[[Path], None]:
    def write(path: Path) -> None:
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text)

    return write


def _write_npy(array: np.ndarray) -> Callable[[Path], None]:
    def write(path: Path) -> None:
        with path.open("wb") as handle:
            np.save(handle, array)

    return write


BAD_FILES: list[tuple[str, Callable[[Path], None] | None, str]] = [
    ("missing.txt", None, "no such map file"),
    ("map.bmp", _write("..."), r"unsupported map format '\.bmp'"),
    ("map", _write("..."), "unsupported map format"),
    ("empty.txt", _write(""), "empty map"),
    ("blank.txt", _write("\n\n"), "empty map"),
    ("walls.txt", _write("###\n###\n"), "no free cell"),
    ("ragged.txt", _write("....\n...\n....\n"), "line 2 has 3 columns, expected 4"),
    ("chars.txt", _write("....\n..x.\n"), r"unknown character 'x' at line 2, col 3"),
    ("starts.txt", _write("S..\n..S\n"), "more than one 'S'"),
    ("cut.txt", _write("S.#..\n..#.D\n"), r"decon area \(1, 4\) is not reachable"),
    ("binary.txt", _write(b"\xff\xfe\x00"), "not a readable text map"),
    ("empty.npy", _write_npy(np.zeros((0, 0), dtype=bool)), "empty map"),
    ("zeros.npy", _write_npy(np.zeros((3, 3), dtype=bool)), "no free cell"),
    ("cube.npy", _write_npy(np.ones((2, 2, 2), dtype=bool)), "2-D grid"),
    ("twos.npy", _write_npy(np.array([[0, 2]])), "bool or 0/1"),
    ("junk.npy", _write(b"not numpy"), "not a readable .npy"),
    ("junk.png", _write(b"not a png"), "not a readable PNG"),
]


@pytest.mark.parametrize(("name", "writer", "message"), BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_bad_map_files_raise_map_error_naming_the_file(
    tmp_path: Path, name: str, writer: Callable[[Path], None] | None, message: str
) -> None:
    path = tmp_path / name
    if writer is not None:
        writer(path)
    with pytest.raises(MapError, match=message) as caught:
        GridMap.load(path)
    assert str(path) in str(caught.value)
    assert isinstance(caught.value, ValueError)


def test_directory_is_not_a_map(tmp_path: Path) -> None:
    folder = tmp_path / "dir.txt"
    folder.mkdir()
    with pytest.raises(MapError, match=re.escape(f"{folder}: no such map file")):
        GridMap.load(folder)


def test_save_rejects_unknown_format(tmp_path: Path) -> None:
    grid = GridMap.from_array(np.ones((2, 2), dtype=bool))
    with pytest.raises(MapError, match=r"unsupported map format '\.gif'"):
        grid.save(tmp_path / "m.gif")
