"""Point-cloud files: read and write (n, 3) float64 points in PLY, PCD, NPY and XYZ text.

Formats, chosen by the file suffix:

- ``.ply``: ``ascii``, ``binary_little_endian`` and ``binary_big_endian``; the ``vertex`` element's
  ``x``, ``y``, ``z`` properties (any numeric type); elements after the vertices are ignored,
  elements before them must not hold list properties in binary files.
- ``.pcd``: ``DATA ascii`` and ``DATA binary`` (PCL's layout); ``binary_compressed`` is refused.
- ``.npy``: an (n, 3) or (n, >3) numeric array (first three columns).
- ``.xyz``, ``.txt``, ``.pts``, ``.csv``: one point per line, the first three numbers (whitespace or
  comma separated); lines starting with ``#`` and a non-numeric header line are skipped.

Every problem raises :class:`PointCloudError` naming the file and what is wrong.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nbv_gym.core.arrayfiles import check_body, declared_count, read_npy
from nbv_gym.core.arrays import FloatArray
from nbv_gym.core.errors import DataFileError, missing_file

SUFFIXES = (".ply", ".pcd", ".npy", ".xyz", ".txt", ".pts", ".csv")

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip
_PCD_TYPES = {("F", 4): "f4", ("F", 8): "f8", ("I", 1): "i1", ("I", 2): "i2", ("I", 4): "i4",
              ("I", 8): "i8", ("U", 1): "u1", ("U", 2): "u2", ("U", 4): "u4", ("U", 8): "u8"}  # fmt: skip


class PointCloudError(DataFileError):
    """A point-cloud file is missing, unreadable, truncated, of an unknown format or empty."""

    def __init__(self, path: str | Path, problem: str):
        super().__init__(f"{path}: {problem}")


def read_points(path: str | Path) -> FloatArray:
    """(n, 3) float64 points of the file at ``path`` (format from the suffix, see the module doc)."""
    path = Path(path)
    readers = {".ply": _read_ply, ".pcd": _read_pcd, ".npy": _read_npy}
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES and not path.is_dir():
        raise PointCloudError(
            path, f"unknown point-cloud format {suffix!r}; use one of {', '.join(SUFFIXES)}"
        )
    if not path.exists() or path.is_dir():
        raise PointCloudError(path, f"the point-cloud file {missing_file(path)}")
    try:
        points = readers.get(suffix, _read_text)(path)
    except PointCloudError:
        raise
    except DataFileError as error:  # a size check of the header (it names the file)
        raise PointCloudError(path, str(error).removeprefix(f"{path}: ")) from None
    except (OSError, ValueError, EOFError, UnicodeDecodeError) as error:
        raise PointCloudError(path, f"unreadable {suffix} file ({error})") from None
    return _checked(path, points)


def write_points(
    path: str | Path,
    points: FloatArray,
    scalars: dict[str, FloatArray] | None = None,
    single: bool = False,
) -> Path:
    """Write (n, 3) points to ``path``: binary PLY, binary PCD, NPY or XYZ text by suffix.

    ``scalars``: per-point (n,) values written beside the coordinates (a PLY vertex property or
    a PCD field of that name — CloudCompare shows them as scalar fields; extra columns in NPY and
    text files). ``single``: coordinates and scalars as float32 (what PCL's ``PointXYZ`` and most
    viewers expect; exact to 4e-6 m below 64 m) instead of float64.
    """
    path = Path(path)
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise PointCloudError(path, f"points must be (n, 3), got {points.shape}")
    columns = {"x": points[:, 0], "y": points[:, 1], "z": points[:, 2], **(scalars or {})}
    for name, values in columns.items():
        if np.shape(values) != (len(points),) or not name.isidentifier():
            raise PointCloudError(path, f"scalar {name!r} must be ({len(points)},) values")
    table = _table(columns, "<f4" if single else "<f8")
    suffix = path.suffix.lower()
    if suffix == ".ply":
        path.write_bytes(_ply_header_text(table).encode() + table.tobytes())
    elif suffix == ".pcd":
        path.write_bytes(_pcd_header_text(table).encode() + table.tobytes())
    elif suffix == ".npy":
        np.save(path, _columns(table))
    elif suffix in SUFFIXES:
        np.savetxt(path, _columns(table), fmt="%.9g", header=" ".join(columns))
    else:
        raise PointCloudError(
            path, f"unknown point-cloud format {suffix!r}; use one of {', '.join(SUFFIXES)}"
        )
    return path


def _table(columns: dict[str, FloatArray], dtype: str) -> np.ndarray:
    """(n,) structured array of the named columns, all of ``dtype``."""
    n = len(columns["x"])
    table = np.empty(n, dtype=[(name, dtype) for name in columns])
    for name, values in columns.items():
        table[name] = values
    return table


def _names(table: np.ndarray) -> tuple[str, ...]:
    """The field names of a structured table (none for a plain array)."""
    return table.dtype.names or ()


def _columns(table: np.ndarray) -> FloatArray:
    """(n, k) plain array of a structured table's columns."""
    return np.stack([table[name] for name in _names(table)], axis=1)


def _ply_header_text(table: np.ndarray) -> str:
    kind = "float" if table.dtype[0].itemsize == 4 else "double"
    properties = "".join(f"property {kind} {name}\n" for name in _names(table))
    return (
        f"ply\nformat binary_little_endian 1.0\ncomment written by nbv-gym\n"
        f"element vertex {len(table)}\n{properties}end_header\n"
    )


def _pcd_header_text(table: np.ndarray) -> str:
    names = _names(table)
    k = len(names)
    size = table.dtype[0].itemsize
    return (
        f"# .PCD v0.7 - written by nbv-gym\nVERSION 0.7\nFIELDS {' '.join(names)}\n"
        f"SIZE {' '.join([str(size)] * k)}\nTYPE {' '.join(['F'] * k)}\n"
        f"COUNT {' '.join(['1'] * k)}\nWIDTH {len(table)}\nHEIGHT 1\n"
        f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(table)}\nDATA binary\n"
    )


def _checked(path: Path, points: FloatArray) -> FloatArray:
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise PointCloudError(path, f"expected (n, 3) points, got shape {points.shape}")
    if len(points) == 0:
        raise PointCloudError(path, "the point cloud is empty")
    if not np.isfinite(points).all():
        raise PointCloudError(path, "the point cloud holds NaN or infinite coordinates")
    return points


def _read_npy(path: Path) -> FloatArray:
    try:
        array = read_npy(path)
    except DataFileError as error:
        raise PointCloudError(path, str(error).removeprefix(f"{path}: ")) from None
    if array.ndim != 2 or array.shape[1] < 3 or array.dtype.kind not in "iuf":
        raise PointCloudError(
            path, f"expected an (n, 3) real numeric array, got {array.dtype} {array.shape}"
        )
    return array[:, :3]


def _read_text(path: Path) -> FloatArray:
    rows: list[list[float]] = []
    for number, line in enumerate(_bytes(path).decode().splitlines(), 1):
        fields = line.replace(",", " ").split()
        if not fields or fields[0].startswith("#"):
            continue
        try:
            values = [float(v) for v in fields[:3]]
        except ValueError:
            if not rows:
                continue  # a header line
            raise PointCloudError(
                path, f"line {number}: not a number in {line.strip()!r}"
            ) from None
        if len(values) < 3:
            raise PointCloudError(
                path, f"line {number}: expected at least 3 numbers, got {len(values)}"
            )
        rows.append(values)
    return np.array(rows, dtype=np.float64).reshape(-1, 3)


def _header_lines(
    path: Path, data: bytes, end_marker: bytes, max_bytes: int = 1 << 16
) -> tuple[list[str], int]:
    """Header lines up to and including the line starting with ``end_marker``; and the body offset."""
    offset = 0
    lines = []
    while offset < min(len(data), max_bytes):
        stop = data.find(b"\n", offset)
        if stop < 0:
            break
        line = data[offset:stop].decode("ascii", errors="replace").strip()
        offset = stop + 1
        lines.append(line)
        if line.upper().startswith(end_marker.decode().upper()):
            return lines, offset
    raise PointCloudError(path, f"no {end_marker.decode()!r} line: not a valid header or truncated")


def _bytes(path: Path) -> bytes:
    """The bytes of the point-cloud file ``path``: a regular file of at most
    :data:`~nbv_gym.core.arrayfiles.MAX_NPZ_BYTES` (:mod:`nbv_gym.core.inputs`)."""
    from nbv_gym.core.arrayfiles import MAX_NPZ_BYTES
    from nbv_gym.core.inputs import read_input

    return read_input(path, "Point-cloud file", MAX_NPZ_BYTES)


def _read_ply(path: Path) -> FloatArray:
    data = _bytes(path)
    if not data.startswith(b"ply"):
        raise PointCloudError(path, "not a PLY file (no 'ply' magic)")
    lines, offset = _header_lines(path, data, b"end_header")
    fmt, elements = _ply_header(path, lines)
    index = next((i for i, e in enumerate(elements) if e[0] == "vertex"), None)
    if index is None:
        raise PointCloudError(path, "no 'vertex' element")
    _, count, props = elements[index]
    names = [name for name, _ in props]
    if not {"x", "y", "z"} <= set(names):
        raise PointCloudError(
            path, f"vertex element lacks x, y, z properties (has {', '.join(names)})"
        )
    if fmt == "ascii":
        total = sum(n for _, n, _ in elements)
        return _ply_ascii(path, data[offset:], elements[:index], count, names, total)
    order = "<" if fmt == "binary_little_endian" else ">"
    skip = 0
    for name, n, p in elements[:index]:
        if any(t.startswith("list") for _, t in p):
            raise PointCloudError(
                path, f"element {name!r} with list properties precedes the vertices"
            )
        skip += n * np.dtype([(pn, order + _PLY_TYPES[t]) for pn, t in p]).itemsize
    if any(t.startswith("list") for _, t in props):
        raise PointCloudError(path, "binary vertices with list properties are not supported")
    dtype = np.dtype([(name, order + _PLY_TYPES[t]) for name, t in props])
    need = skip + count * dtype.itemsize
    after = elements[index + 1 :]
    if any(t.startswith("list") for _, _, p in after for _, t in p):  # faces: size unknown
        check_body(path, f"a body of {count} vertices", need, min(need, len(data) - offset))
    else:
        need += sum(n * np.dtype([(pn, order + _PLY_TYPES[t]) for pn, t in p]).itemsize
                    for _, n, p in after)  # fmt: skip
        check_body(path, f"a body of {count} vertices", need, len(data) - offset)
    vertices = np.frombuffer(data, dtype=dtype, count=count, offset=offset + skip)
    return np.stack([vertices[c].astype(np.float64) for c in "xyz"], axis=1)


def _ply_header(path: Path, lines: list[str]):
    fmt: str | None = None
    elements: list[tuple[str, int, list[tuple[str, str]]]] = []
    for line in lines[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info", "end_header"):
            continue
        if words[0] == "format":
            fmt = words[1] if len(words) > 1 else None
        elif words[0] == "element" and len(words) == 3:
            count = declared_count(words[2], path, f"the count of element {words[1]!r}")
            elements.append((words[1], count, []))
        elif words[0] == "property" and elements:
            kind = "list " + words[-2] if words[1] == "list" else words[1]
            if words[1] != "list" and kind not in _PLY_TYPES:
                raise PointCloudError(path, f"unknown PLY property type {kind!r}")
            elements[-1][2].append((words[-1], kind))
        else:
            raise PointCloudError(path, f"unexpected PLY header line {line!r}")
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise PointCloudError(path, f"unknown PLY format {fmt!r}")
    return fmt, elements


def _ply_ascii(
    path: Path, body: bytes, before, count: int, names: list[str], total_lines: int
) -> FloatArray:
    lines = [line for line in body.decode("ascii", errors="replace").splitlines() if line.strip()]
    skip = sum(n for _, n, _ in before)
    rows = [line.split() for line in lines[skip : skip + count]]
    if len(rows) < count or any(len(r) < len(names) for r in rows):
        raise PointCloudError(
            path, f"truncated: expected {count} vertex lines of {len(names)} values"
        )
    if len(lines) > total_lines:
        raise PointCloudError(
            path, f"the header declares {total_lines} element lines ({count} vertices) but the "
            f"body holds {len(lines)}; the header does not describe the whole file",
        )  # fmt: skip
    table = np.array([r[: len(names)] for r in rows], dtype=np.float64).reshape(count, len(names))
    return table[:, [names.index(c) for c in "xyz"]]


def _read_pcd(path: Path) -> FloatArray:
    data = _bytes(path)
    lines, offset = _header_lines(path, data, b"DATA")
    header = {}
    for line in lines:
        if line and not line.startswith("#"):
            key, *values = line.split()
            header[key.upper()] = values
    fields = header.get("FIELDS", [])
    if not {"x", "y", "z"} <= set(fields):
        raise PointCloudError(path, f"PCD FIELDS lack x, y, z (has {' '.join(fields) or 'none'})")
    count = _pcd_count(path, header)
    kind = header["DATA"][0].lower() if header.get("DATA") else ""
    if kind == "ascii":
        table = np.loadtxt(data[offset:].decode("ascii").splitlines(), ndmin=2)
        if len(table) != count or table.shape[1] < len(fields):
            raise PointCloudError(
                path, f"POINTS declares {count} rows of {len(fields)} values, the body holds "
                f"{len(table)} rows of {table.shape[1] if table.size else 0}",
            )  # fmt: skip
        return table[:, [fields.index(c) for c in "xyz"]]
    if kind != "binary":
        raise PointCloudError(path, f"unsupported PCD DATA {kind!r}; save it as ascii or binary")
    return _pcd_binary(path, data, offset, header, fields, count)


def _pcd_count(path: Path, header: dict[str, list[str]]) -> int:
    """POINTS of a PCD header, checked: an integer ≥ 0 equal to WIDTH · HEIGHT when given."""
    count = declared_count((header.get("POINTS") or ["0"])[0], path, "POINTS")
    if "WIDTH" in header and "HEIGHT" in header:
        width = declared_count(header["WIDTH"][0], path, "WIDTH")
        height = declared_count(header["HEIGHT"][0], path, "HEIGHT")
        if width * height != count:
            raise PointCloudError(
                path, f"POINTS {count} differs from WIDTH · HEIGHT = {width} · {height}"
            )
    return count


def _pcd_binary(path: Path, data: bytes, offset: int, header, fields, count) -> FloatArray:
    sizes = [int(v) for v in header.get("SIZE", [])]
    types = header.get("TYPE", [])
    counts = [declared_count(v, path, "a COUNT") for v in header.get("COUNT", ["1"] * len(fields))]
    if 0 in counts:
        raise PointCloudError(path, "COUNT 0 declares a field without values; expected ≥ 1")
    if not (len(sizes) == len(types) == len(counts) == len(fields)):
        raise PointCloudError(path, "PCD FIELDS, SIZE, TYPE and COUNT have different lengths")
    try:
        dtype = np.dtype(
            [
                (f, "<" + _PCD_TYPES[(t.upper(), s)], (c,))
                for f, s, t, c in zip(fields, sizes, types, counts, strict=True)
            ]
        )
    except KeyError as error:
        raise PointCloudError(path, f"unsupported PCD field type {error.args[0]}") from None
    check_body(path, f"a body of {count} points", count * dtype.itemsize,
               len(data) - offset)  # fmt: skip
    table = np.frombuffer(data, dtype=dtype, count=count, offset=offset)
    return np.stack([table[c][:, 0].astype(np.float64) for c in "xyz"], axis=1)
