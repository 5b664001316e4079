#!/usr/bin/env python3
"""Writes the measured-surface fixtures read by tests/measured_formats.rs.

Independent of toolmark: only the Python standard library (zipfile, struct, hashlib,
zlib-free hand-written EXR), and every height follows a formula the Rust test repeats:

    sample.x3p          SUR 5 x 4, DataType D, z = 1e-7 * (i - 2 j) m, NaN at (2, 1);
                        CX 2 um from 10 um, CY 3 um from -20 um
    sample_prf.x3p      PRF 7 points, DataType F, z = 2e-8 i^2 - 1e-7 m; CX 0.5 um from 0
    sample_int.x3p      SUR 4 x 3, DataType I, raw = 10 i - 7 j, CZ Increment 1e-9,
                        Offset 5e-9, validity mask clearing points k = 1 and k = 10
    sample_inline.x3p   SUR 3 x 2, inline DataList, z = 1e-6 * (i + j) m, Datum 4 empty
    sample_absolute.x3p like sample.x3p but CX AxisType A (must be refused)
    sample_no_main.x3p  a zip without main.xml (must be refused)
    sample.gsf          6 x 3, z = 1e-8 * (i + 10 j) m (f32), NaN at (5, 2);
                        1.5 um x 2 um pixels, corner at (-4.5 um, 1 um)
    sample.exr          4 x 3 FLOAT channels height_um = 0.25 i - 0.5 j + 1 and valid
                        (0 at (3, 0)); float/double/string pitch and origin attributes
    sample_grid.csv     5 x 4, z = 3 i - 2 j + 0.5 nm, 2.5 x 4 um pixels from (10, -20) um,
                        empty cell at (1, 2), NaN at (4, 3)
    sample_profile.csv  20 points x = 0.5 k um, z = 4 k - 0.25 k^2 nm, `***` at k = 7
    sample_line.xyz     16 points on a line from (1, 2) mm along (0.6, 0.8):
                        s = 0.1 k mm, z = 0.5 s^2 um (s in mm)
    sample_grid.xyz     4 x 3 lattice from (-1, 0.5) mm, steps 0.25 / 0.125 mm,
                        z = i j + 1 nm, point (3, 2) missing, rows shuffled

Run from anywhere: python3 tests/data/measured/make_fixtures.py
"""

import hashlib
import random
import struct
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
NAN = float("nan")


def md5(data: bytes) -> str:
    return hashlib.md5(data).hexdigest()


def axis(name, axis_type, data_type, increment, offset):
    parts = [f"<{name}><AxisType>{axis_type}</AxisType>"]
    if data_type:
        parts.append(f"<DataType>{data_type}</DataType>")
    if increment is not None:
        parts.append(f"<Increment>{increment!r}</Increment>")
    if offset is not None:
        parts.append(f"<Offset>{offset!r}</Offset>")
    parts.append(f"</{name}>")
    return "".join(parts)


def main_xml(feature, axes, size, record3_data, prefix=""):
    """An ISO 5436-2 main.xml; `prefix` qualifies the child elements (p:Record1...)."""
    p = prefix
    nx, ny = size
    xml = f"""<?xml version="1.0" encoding="UTF-8"?>
<!-- written by make_fixtures.py -->
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
  <{p}Record1>
    <{p}Revision>ISO5436 - 2000</{p}Revision>
    <{p}FeatureType>{feature}</{p}FeatureType>
    <{p}Axes>
      {axes}
    </{p}Axes>
  </{p}Record1>
  <{p}Record2>
    <{p}Date>2024-01-01T00:00:00Z</{p}Date>
    <{p}Creator>make_fixtures.py</{p}Creator>
  </{p}Record2>
  <{p}Record3>
    <{p}MatrixDimension>
      <{p}SizeX>{nx}</{p}SizeX>
      <{p}SizeY>{ny}</{p}SizeY>
      <{p}SizeZ>1</{p}SizeZ>
    </{p}MatrixDimension>
    {record3_data}
  </{p}Record3>
  <{p}Record4>
    <{p}ChecksumFile>md5checksum.hex</{p}ChecksumFile>
  </{p}Record4>
</p:ISO5436_2>
"""
    return xml.encode("utf-8")


def write_zip(path, entries):
    """entries: (name, bytes, compression) in order; fixed timestamps."""
    with zipfile.ZipFile(path, "w") as z:
        for name, data, method in entries:
            info = zipfile.ZipInfo(name, date_time=(2024, 1, 1, 0, 0, 0))
            info.compress_type = method
            z.writestr(info, data)


def x3p(path, xml, data_entries):
    write_zip(
        path,
        [("main.xml", xml, zipfile.ZIP_STORED)]
        + data_entries
        + [("md5checksum.hex", f"{md5(xml)} *main.xml\n".encode(), zipfile.ZIP_STORED)],
    )


def data_link(data, valid=None):
    link = (
        "<DataLink><PointDataLink>bindata/data.bin</PointDataLink>"
        f"<MD5ChecksumPointData>{md5(data)}</MD5ChecksumPointData>"
    )
    if valid is not None:
        link += (
            "<ValidPointsLink>bindata/valid.bin</ValidPointsLink>"
            f"<MD5ChecksumValidPoints>{md5(valid)}</MD5ChecksumValidPoints>"
        )
    return link + "</DataLink>"


def sample_x3p(name, cx_type="I"):
    nx, ny = 5, 4
    z = [1e-7 * (i - 2 * j) for j in range(ny) for i in range(nx)]
    z[1 * nx + 2] = NAN
    data = struct.pack(f"<{nx * ny}d", *z)
    axes = (
        axis("CX", cx_type, "D", 2e-6, 1e-5)
        + axis("CY", "I", "D", 3e-6, -2e-5)
        + axis("CZ", "A", "D", None, None)
    )
    xml = main_xml("SUR", axes, (nx, ny), data_link(data))
    x3p(HERE / name, xml, [("bindata/data.bin", data, zipfile.ZIP_DEFLATED)])


def sample_prf():
    n = 7
    z = [2e-8 * i * i - 1e-7 for i in range(n)]
    data = struct.pack(f"<{n}f", *z)
    axes = (
        axis("p:CX", "I", "D", 0.5e-6, 0.0)
        + axis("p:CY", "I", "D", 1.0, 0.0)
        + axis("p:CZ", "A", "F", None, None)
    )
    xml = main_xml("PRF", axes, (n, 1), data_link(data).replace("<", "<p:").replace("<p:/", "</p:"), "p:")
    x3p(HERE / "sample_prf.x3p", xml, [("bindata/data.bin", data, zipfile.ZIP_DEFLATED)])


def sample_int():
    nx, ny = 4, 3
    raw = [10 * i - 7 * j for j in range(ny) for i in range(nx)]
    data = struct.pack(f"<{nx * ny}h", *raw)
    invalid = {1, 10}
    bits = [0 if k in invalid else 1 for k in range(nx * ny)]
    valid = bytes(
        sum(bits[k] << (k % 8) for k in range(b * 8, min(b * 8 + 8, len(bits))))
        for b in range((len(bits) + 7) // 8)
    )
    axes = (
        axis("CX", "I", "D", 1e-6, 0.0)
        + axis("CY", "I", "D", 1e-6, 0.0)
        + axis("CZ", "A", "I", 1e-9, 5e-9)
    )
    xml = main_xml("SUR", axes, (nx, ny), data_link(data, valid))
    x3p(
        HERE / "sample_int.x3p",
        xml,
        [
            ("bindata/data.bin", data, zipfile.ZIP_DEFLATED),
            ("bindata/valid.bin", valid, zipfile.ZIP_STORED),
        ],
    )


def sample_inline():
    nx, ny = 3, 2
    datums = []
    for k in range(nx * ny):
        i, j = k % nx, k // nx
        datums.append("<Datum/>" if k == 4 else f"<Datum>{1e-6 * (i + j)!r}</Datum>")
    axes = (
        axis("CX", "I", "D", 1e-6, 0.0)
        + axis("CY", "I", "D", 1e-6, 0.0)
        + axis("CZ", "A", "D", None, None)
    )
    xml = main_xml("SUR", axes, (nx, ny), "<DataList>" + "".join(datums) + "</DataList>")
    x3p(HERE / "sample_inline.x3p", xml, [])


def sample_no_main():
    write_zip(
        HERE / "sample_no_main.x3p",
        [("bindata/data.bin", struct.pack("<4d", 1, 2, 3, 4), zipfile.ZIP_STORED)],
    )


def sample_gsf():
    nx, ny = 6, 3
    z = [1e-8 * (i + 10 * j) for j in range(ny) for i in range(nx)]
    z[2 * nx + 5] = NAN
    header = (
        "Gwyddion Simple Field 1.0\n"
        f"XRes = {nx}\nYRes = {ny}\n"
        f"XReal = {nx * 1.5e-6!r}\nYReal = {ny * 2e-6!r}\n"
        "XOffset = -4.5e-6\nYOffset = 1e-6\n"
        "XYUnits = m\nZUnits = m\nTitle = make_fixtures.py\n"
    ).encode()
    header += b"\0" * (4 - len(header) % 4)
    (HERE / "sample.gsf").write_bytes(header + struct.pack(f"<{nx * ny}f", *z))


def exr_attribute(name, type_name, value: bytes) -> bytes:
    return name.encode() + b"\0" + type_name.encode() + b"\0" + struct.pack("<i", len(value)) + value


def sample_exr():
    """An uncompressed single-part scan-line OpenEXR file, written by hand."""
    nx, ny = 4, 3
    channels = ["height_um", "valid"]  # sorted, as the format requires
    height = [[0.25 * i - 0.5 * j + 1 for i in range(nx)] for j in range(ny)]
    valid = [[0.0 if (i, j) == (3, 0) else 1.0 for i in range(nx)] for j in range(ny)]
    chlist = b"".join(
        c.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for c in channels
    ) + b"\0"
    box = struct.pack("<iiii", 0, 0, nx - 1, ny - 1)
    header = b"".join(
        [
            struct.pack("<I", 20000630),  # magic number 0x762f3101
            struct.pack("<I", 2),  # version 2, single-part scan lines
            exr_attribute("channels", "chlist", chlist),
            exr_attribute("compression", "compression", b"\0"),
            exr_attribute("dataWindow", "box2i", box),
            exr_attribute("displayWindow", "box2i", box),
            exr_attribute("lineOrder", "lineOrder", b"\0"),
            exr_attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
            exr_attribute("pixel_x_um", "float", struct.pack("<f", 1.25)),
            exr_attribute("pixel_y_um", "double", struct.pack("<d", 2.5)),
            exr_attribute("screenWindowCenter", "v2f", struct.pack("<ff", 0, 0)),
            exr_attribute("screenWindowWidth", "float", struct.pack("<f", 1.0)),
            exr_attribute("x0_mm", "string", b"0.5"),
            exr_attribute("y0_mm", "float", struct.pack("<f", -0.25)),
            b"\0",
        ]
    )
    line_bytes = 4 * nx * len(channels)
    table_end = len(header) + 8 * ny
    offsets = [table_end + j * (8 + line_bytes) for j in range(ny)]
    body = b"".join(
        struct.pack("<ii", j, line_bytes)
        + struct.pack(f"<{nx}f", *height[j])
        + struct.pack(f"<{nx}f", *valid[j])
        for j in range(ny)
    )
    (HERE / "sample.exr").write_bytes(header + struct.pack(f"<{ny}Q", *offsets) + body)


def sample_grid_csv():
    nx, ny = 5, 4
    lines = [
        "# a height map written by make_fixtures.py",
        "# pixel_x_um = 2.5",
        "# pixel_y_um = 4",
        "# x0_um = 10",
        "# y0_um = -20",
        "# height_unit = nm",
    ]
    for j in range(ny):
        cells = []
        for i in range(nx):
            if (i, j) == (1, 2):
                cells.append("")
            elif (i, j) == (4, 3):
                cells.append("NaN")
            else:
                cells.append(repr(3 * i - 2 * j + 0.5))
        lines.append(",".join(cells))
    (HERE / "sample_grid.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")


def sample_profile_csv():
    lines = ["# profile written by make_fixtures.py", "X (µm),Z [nm]"]
    for k in range(20):
        z = "***" if k == 7 else repr(4 * k - 0.25 * k * k)
        lines.append(f"{0.5 * k!r},{z}")
    (HERE / "sample_profile.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")


def sample_line_xyz():
    lines = ["# lateral_unit = mm", "# height_unit = um"]
    for k in range(16):
        s = 0.1 * k
        lines.append(f"{1 + 0.6 * s!r} {2 + 0.8 * s!r} {0.5 * s * s!r}")
    (HERE / "sample_line.xyz").write_text("\n".join(lines) + "\n", encoding="utf-8")


def sample_grid_xyz():
    rows = []
    for j in range(3):
        for i in range(4):
            if (i, j) != (3, 2):
                rows.append(f"{-1 + 0.25 * i!r}\t{0.5 + 0.125 * j!r}\t{i * j + 1!r}")
    random.Random(5).shuffle(rows)
    text = "x_mm\ty_mm\tz_nm\n" + "\n".join(rows) + "\n"
    (HERE / "sample_grid.xyz").write_text(text, encoding="utf-8")


if __name__ == "__main__":
    sample_x3p("sample.x3p")
    sample_x3p("sample_absolute.x3p", cx_type="A")
    sample_prf()
    sample_int()
    sample_inline()
    sample_no_main()
    sample_gsf()
    sample_exr()
    sample_grid_csv()
    sample_profile_csv()
    sample_line_xyz()
    sample_grid_xyz()
