"""NanoVDB files (.nvdb) read with numpy: what a scene checks before any kernel runs.

A NanoVDB file (Museth 2021, NanoVDB.h / PNanoVDB.h in AcademySoftwareFoundation/openvdb,
ABI major version 32) is a 16-byte file header (magic "NanoVDB0" or "NanoVDB2", version,
grid count, codec), one 176-byte metadata record and a name per grid, then the grids'
buffers, each compressed by the codec (0 none, 1 zip: chunks of a uint64 size and zlib
data). A grid buffer opens with the 672-byte GridData (magic "NanoVDB0"/"NanoVDB1", version,
grid size, the index-to-world map at 296, grid class at 632 and value type at 636), then the
64-byte TreeData (byte offsets from it of the first leaf, lower, upper and root node, and
their counts), the root (index bounding box of the active voxels, table size, background),
the upper (32^3 children) and lower (16^3) internal nodes and the 8^3 leaves. A float grid's
leaf is 2144 bytes, its 512 values from byte 96; an internal node's table holds, per entry,
a child offset or a tile value (a constant over the child's region).

``read_grid`` checks all of that for the first grid of a file and the values' range (finite,
>= 0: it reads every leaf, tile and the background); ``sample_frame`` maps a medium's bounds
onto the grid's voxels. The values themselves stay in the file: ``warpvol.upload`` loads the
grid with ``wp.Volume.load_from_nvdb`` for the kernels.

Voxel (i, j, k)'s value sits at the world position map(i, j, k), the voxel's centre (the
voxel spans map(i -+ 1/2)): Warp's trilinear ``volume_sample_f`` blends the voxels around an
index-space point with integer coordinates at the voxels, the dense grid's cell-centred
convention (media/grid.py).
"""

from __future__ import annotations

import math
import os
import zlib

import numpy as np

from .model import NanoVDBGrid

MAGIC_FILE = (0x304244566F6E614E, 0x324244566F6E614E)  # "NanoVDB0", "NanoVDB2", little-endian
MAGIC_GRID = (0x304244566F6E614E, 0x314244566F6E614E)  # "NanoVDB0", "NanoVDB1"
MAJOR_VERSION = 32  # the ABI; version = major << 21 | minor << 10 | patch

FILE_HEADER = 16
FILE_METADATA = 176
GRID_DATA = 672
TREE_DATA = 64

GRID_TYPES = ["unknown", "float", "double", "int16", "int32", "int64", "Vec3f", "Vec3d", "mask", "half", "uint32",
              "bool", "RGBA8", "Fp4", "Fp8", "Fp16", "FpN", "Vec4f", "Vec4d", "index", "on-index", "index-mask",
              "on-index-mask", "point-index", "Vec3u8", "Vec3u16", "uint8"]
FLOAT = 1
INDEX_TYPES = (19, 20, 21, 22, 23)
GRID_CLASSES = ["unknown", "level set", "fog volume", "staggered", "point index", "point data", "topology",
                "voxel volume", "index grid", "tensor grid"]
DENSITY_CLASSES = (0, 2)  # unknown, fog volume

# float grids (PNanoVDB.h, pnanovdb_grid_type_constants[FLOAT])
ROOT_BACKGROUND, ROOT_SIZE, ROOT_TILE_VALUE, ROOT_TILE_SIZE = 28, 64, 20, 32
UPPER_CHILD_MASK, UPPER_TABLE, UPPER_SIZE, UPPER_ENTRIES = 4128, 8256, 270400, 32768
LOWER_CHILD_MASK, LOWER_TABLE, LOWER_SIZE, LOWER_ENTRIES = 544, 1088, 33856, 4096
LEAF_VALUES, LEAF_SIZE = 96, 2144

ALLOWED = "a NanoVDB file (.nvdb, uncompressed or zip) of a float grid of class fog volume or unknown, as " \
          "warpvol.save_volume writes"

#: Leaves checked per numpy pass (bounds the temporaries to a few MB).
CHUNK = 4096


class NanoVDBError(ValueError):
    """A file that is not a NanoVDB float density grid: ``problem`` says what is wrong, ``allowed`` what is."""

    def __init__(self, problem: str, allowed: str = ALLOWED):
        super().__init__(f"{problem} (allowed: {allowed})")
        self.problem = problem
        self.allowed = allowed


def is_nanovdb(path: str) -> bool:
    """Whether the file starts with a NanoVDB file signature."""
    with open(path, "rb") as fh:
        head = fh.read(8)
    return len(head) == 8 and int.from_bytes(head, "little") in MAGIC_FILE


def _u(buf, offset: int, dtype, count: int = 1):
    return np.frombuffer(buf, dtype, count, offset)


def _grid_buffer(path: str) -> np.ndarray:
    """The first grid's buffer (uint8), decompressed; the file header and metadata checked."""
    size = os.path.getsize(path)
    if size < FILE_HEADER:
        raise NanoVDBError(f"is truncated: {size} bytes, less than a NanoVDB file header")
    data = np.memmap(path, np.uint8, "r")
    magic = int(_u(data, 0, "<u8")[0])
    version, grid_count, codec = int(_u(data, 8, "<u4")[0]), int(_u(data, 12, "<u2")[0]), int(_u(data, 14, "<u2")[0])
    if magic not in MAGIC_FILE:
        raise NanoVDBError("is not a NanoVDB file (no NanoVDB0 or NanoVDB2 signature)")
    if version >> 21 != MAJOR_VERSION:
        raise NanoVDBError(f"has NanoVDB version {version >> 21}.{(version >> 10) & 2047}.{version & 1023}",
                           f"major version {MAJOR_VERSION}")
    if grid_count < 1:
        raise NanoVDBError("holds no grid")
    if codec not in (0, 1):
        raise NanoVDBError(f"is compressed with codec {codec}{' (blosc)' if codec == 2 else ''}", "uncompressed or zip")
    offset, sizes = FILE_HEADER, []
    for _ in range(grid_count):  # the metadata of every grid, then the grids' data
        if offset + FILE_METADATA > size:
            raise NanoVDBError(f"is truncated: {size} bytes end inside the metadata of grid {len(sizes)}")
        grid_size, file_size = (int(v) for v in _u(data, offset, "<u8", 2))
        sizes.append((grid_size, file_size))
        offset += FILE_METADATA + int(_u(data, offset + 136, "<u4")[0])
    grid_size, file_size = sizes[0]
    if offset + file_size > size:
        raise NanoVDBError(f"is truncated: {size} bytes, the header promises {offset + file_size}")
    if codec == 0:
        grid = data[offset : offset + grid_size]
    else:
        chunks, end, got = [], offset + file_size, 0
        try:
            while offset < end and got < grid_size:
                n = int(_u(data, offset, "<u8")[0])
                chunks.append(zlib.decompress(data[offset + 8 : offset + 8 + n]))
                got += len(chunks[-1])
                offset += 8 + n
        except (zlib.error, ValueError) as exc:
            raise NanoVDBError(f"has corrupt zip data ({exc})") from None
        grid = np.frombuffer(b"".join(chunks), np.uint8)
    if len(grid) < max(grid_size, GRID_DATA + TREE_DATA):
        raise NanoVDBError(f"is truncated: the grid holds {len(grid)} bytes, its header promises {grid_size}")
    return grid


def _check_values(values: np.ndarray, where: str) -> float:
    """The largest of ``values`` (float32), which must be finite and >= 0; 0 for none."""
    if not values.size:
        return 0.0
    lo, hi = float(values.min()), float(values.max())
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo < 0.0:
        raise NanoVDBError(f"has {where} with NaN, Inf or negative values (from {lo:g} to {hi:g})",
                           "finite densities >= 0")
    return hi


def _tile_values(grid: np.ndarray, first: int, count: int, size: int, mask_at: int, table_at: int,
                 entries: int) -> np.ndarray:
    """The tile values (table entries without a child) of ``count`` internal nodes from ``first``."""
    out = []
    for k in range(count):
        node = first + k * size
        child = np.unpackbits(grid[node + mask_at : node + mask_at + entries // 8], bitorder="little").astype(bool)
        table = np.frombuffer(grid, "<f4", 2 * entries, node + table_at)[0::2]  # a value in the low 4 of 8 bytes
        out.append(table[~child])
    return np.concatenate(out) if out else np.zeros(0, np.float32)


def read_grid(path: str) -> NanoVDBGrid:
    """The first grid of the NanoVDB file ``path``, checked: a float density grid (not an index
    grid, a level set or another value type), axis-aligned voxels, every node inside the buffer,
    every value (leaves, tiles, background) finite and >= 0. Raises ``NanoVDBError``."""
    grid = _grid_buffer(path)
    magic, grid_size = int(_u(grid, 0, "<u8")[0]), int(_u(grid, 32, "<u8")[0])
    version = int(_u(grid, 16, "<u4")[0])
    grid_class, grid_type = (int(v) for v in _u(grid, 632, "<u4", 2))
    if magic not in MAGIC_GRID:
        raise NanoVDBError("is corrupt: its grid has no NanoVDB0 or NanoVDB1 signature")
    if version >> 21 != MAJOR_VERSION:
        raise NanoVDBError(f"has a grid of NanoVDB version {version >> 21}", f"major version {MAJOR_VERSION}")
    type_name = GRID_TYPES[grid_type] if grid_type < len(GRID_TYPES) else f"type {grid_type}"
    if grid_type in INDEX_TYPES or grid_class == 8:
        raise NanoVDBError(f"holds an index grid ({type_name}: offsets into other arrays, no values)")
    if grid_type != FLOAT:
        raise NanoVDBError(f"holds a grid of {type_name} values, not float")
    if grid_class not in DENSITY_CLASSES:
        name = GRID_CLASSES[grid_class] if grid_class < len(GRID_CLASSES) else f"class {grid_class}"
        raise NanoVDBError(f"holds a {name} grid, not a density (fog volume)")
    mat, vec = _u(grid, 384, "<f8", 9).reshape(3, 3), _u(grid, 528, "<f8", 3)
    h = np.diag(mat)
    if not (np.all(np.isfinite(mat)) and np.all(np.isfinite(vec))) or np.any(mat[~np.eye(3, dtype=bool)] != 0.0) \
            or np.any(h <= 0.0):
        raise NanoVDBError(f"has an index-to-world map {mat.tolist()} that is not a positive scale per axis",
                           "axis-aligned voxels: a diagonal map with positive voxel sizes")
    tree = GRID_DATA
    leaf_at, lower_at, upper_at, root_at = (tree + int(v) for v in _u(grid, tree, "<u8", 4))
    leaves, lowers, uppers = (int(v) for v in _u(grid, tree + 32, "<u4", 3))
    voxels = int(_u(grid, tree + 56, "<u8")[0])
    ends = [(leaf_at, leaves, LEAF_SIZE), (lower_at, lowers, LOWER_SIZE), (upper_at, uppers, UPPER_SIZE),
            (root_at, 1, ROOT_SIZE)]
    if any(first < GRID_DATA + TREE_DATA or first + n * size > grid_size for first, n, size in ends):
        raise NanoVDBError(f"is truncated or corrupt: its tree reaches past the grid's {grid_size} bytes")
    table = int(_u(grid, root_at + 24, "<u4")[0])
    if root_at + ROOT_SIZE + table * ROOT_TILE_SIZE > grid_size:
        raise NanoVDBError(f"is truncated or corrupt: its root table reaches past the grid's {grid_size} bytes")
    bbox = _u(grid, root_at, "<i4", 6)
    value_max = 0.0
    for k in range(0, leaves, CHUNK):
        n = min(CHUNK, leaves - k)
        block = np.frombuffer(grid, "<f4", n * LEAF_SIZE // 4, leaf_at + k * LEAF_SIZE).reshape(n, LEAF_SIZE // 4)
        value_max = max(value_max, _check_values(block[:, LEAF_VALUES // 4 :], "voxels"))
    tiles = [np.frombuffer(grid, "<f4", 1, root_at + ROOT_BACKGROUND)]
    tiles.append(_tile_values(grid, lower_at, lowers, LOWER_SIZE, LOWER_CHILD_MASK, LOWER_TABLE, LOWER_ENTRIES))
    tiles.append(_tile_values(grid, upper_at, uppers, UPPER_SIZE, UPPER_CHILD_MASK, UPPER_TABLE, UPPER_ENTRIES))
    root_tiles = np.frombuffer(grid, np.uint8, table * ROOT_TILE_SIZE, root_at + ROOT_SIZE).reshape(-1, ROOT_TILE_SIZE)
    no_child = root_tiles[:, 8:16].copy().view("<i8")[:, 0] == 0
    tiles.append(root_tiles[no_child, ROOT_TILE_VALUE : ROOT_TILE_VALUE + 4].copy().view("<f4")[:, 0])
    outside = _check_values(np.concatenate(tiles), "tile or background values")
    return NanoVDBGrid(path=os.path.abspath(path), voxel_size=tuple(float(v) for v in h),
                       origin=tuple(float(v) for v in vec), active_min=tuple(int(v) for v in bbox[:3]),
                       active_max=tuple(int(v) for v in bbox[3:]), leaves=leaves, voxels=voxels,
                       value_max=max(value_max, outside), outside_leaves=outside, grid_bytes=grid_size)


def voxel_faces(grid: NanoVDBGrid, lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """World positions of the faces that bound voxels ``lo`` to ``hi`` (index, inclusive)."""
    h, o = np.asarray(grid.voxel_size), np.asarray(grid.origin)
    return o + (np.asarray(lo) - 0.5) * h, o + (np.asarray(hi) + 0.5) * h


def active_faces(grid: NanoVDBGrid) -> tuple[tuple, tuple]:
    """The faces around the grid's active voxels: the bounds a medium takes by default."""
    lo, hi = voxel_faces(grid, grid.active_min, grid.active_max)
    return tuple(float(v) for v in lo), tuple(float(v) for v in hi)


def sample_frame(grid: NanoVDBGrid, bounds_min, bounds_max) -> tuple[tuple, tuple]:
    """(index of the voxel that is sample (0, 0, 0), samples per axis (x, y, z)) of the medium
    whose bounds are ``bounds_min`` to ``bounds_max``: the bounds must lie on voxel faces (within
    a thousandth of a voxel, plus float32 rounding of the map), so that the voxels inside are the
    cell-centred samples of a dense grid over the bounds. Raises ``NanoVDBError`` whose problem
    starts with the key (``bounds_min`` or ``bounds_max``)."""
    h, o = np.asarray(grid.voxel_size), np.asarray(grid.origin)
    faces = []
    for key, b in (("bounds_min", np.asarray(bounds_min, np.float64)), ("bounds_max", np.asarray(bounds_max))):
        u = (b - o) / h + 0.5  # the face of voxel i lies at index i - 1/2
        tol = 1e-3 + 2.0**-20 * (np.abs(b) + np.abs(o)) / h
        if np.any(np.abs(u - np.round(u)) > tol):
            near = o + (np.round(u) - 0.5) * h
            span = active_faces(grid)
            raise NanoVDBError(f"{key}: {b.tolist()} does not lie on voxel faces of {grid.path!r} (voxel size "
                               f"{list(grid.voxel_size)}, voxel (0, 0, 0) centred at {list(grid.origin)})",
                               f"voxel faces, e.g. {[float(f'{v:.7g}') for v in near]}; the active voxels span "
                               f"{[float(f'{v:.7g}') for v in span[0]]} to {[float(f'{v:.7g}') for v in span[1]]}")
        faces.append(np.round(u).astype(np.int64))
    first, dims = faces[0], faces[1] - faces[0]
    return tuple(int(v) for v in first), tuple(int(v) for v in dims)
