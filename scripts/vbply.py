"""Reads the vertices of a PLY file as vbutcher and virtualbutcherd write them (io/ply.cc):
ascii or binary little-endian, the vertex element first, scalar vertex properties, x y z among
them. Shared by scripts/plot-carcass, scripts/plot-bench and tests/tools/bench_shapes_test.sh.
Needs numpy (python3-numpy, which python3-matplotlib brings)."""
import numpy as np

_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "<i2", "int16": "<i2",
          "ushort": "<u2", "uint16": "<u2", "int": "<i4", "int32": "<i4", "uint": "<u4",
          "uint32": "<u4", "float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8"}


def read_vertices(path):
    """The vertices' x y z as an (n, 3) float64 array. Exits naming @p path and what is wrong
    for a file that is not such a PLY (SystemExit, no traceback)."""
    try:
        return _read(path)
    except (ValueError, IndexError, UnicodeDecodeError) as e:
        raise SystemExit(f"{path}: not a readable PLY file: {e}")


def _read(path):
    with open(path, "rb") as f:
        data = f.read()
    marker = b"end_header\n"
    if not data.startswith(b"ply\n") or marker not in data:
        raise SystemExit(f"{path}: not a PLY file (no 'ply' line or no end_header)")
    end = data.index(marker) + len(marker)
    header = data[:end].decode("ascii").splitlines()
    formats = [l.split() for l in header if l.startswith("format ")]
    fmt = formats[0][1] if formats and len(formats[0]) > 1 else ""
    elements = [l.split() for l in header if l.startswith("element ")]
    if not elements or elements[0][1:2] != ["vertex"]:
        raise SystemExit(f"{path}: the first element is not 'vertex'")
    count = int(elements[0][2])
    if count < 0:
        raise SystemExit(f"{path}: element vertex {count}: a negative count")
    props = []
    first = next(i for i, l in enumerate(header) if l.startswith("element "))
    for line in header[first + 1:]:
        words = line.split()
        if words[:1] == ["element"]:
            break  # the vertex element's properties end here
        if words[:1] == ["property"]:
            if len(words) != 3 or words[1] not in _TYPES:
                raise SystemExit(f"{path}: vertex property '{line}' is not a scalar PLY type")
            props.append((words[2], _TYPES[words[1]]))
    names = [n for n, _ in props]
    if not {"x", "y", "z"} <= set(names):
        raise SystemExit(f"{path}: the vertex element has no x, y and z")
    if fmt == "binary_little_endian":
        record = np.dtype([(n, t) for n, t in props])
        if len(data) - end < count * record.itemsize:
            raise SystemExit(f"{path}: {count} vertices announced, the file is shorter")
        table = np.frombuffer(data, dtype=record, count=count, offset=end)
        return np.stack([table[a].astype(float) for a in "xyz"], axis=1)
    if fmt != "ascii":
        raise SystemExit(f"{path}: PLY format '{fmt}' (ascii or binary_little_endian only)")
    rows = data[end:].decode("ascii").splitlines()[:count]
    if len(rows) != count or any(len(r.split()) != len(names) for r in rows):
        raise SystemExit(f"{path}: {count} vertices of {len(names)} values announced, "
                         "the file holds others")
    values = np.array([r.split() for r in rows], dtype=float).reshape(count, len(names))
    return values[:, [names.index(a) for a in "xyz"]]
