#!/usr/bin/env python3
"""Regenerates the binary fixtures of tests/integration/mesh_io.rs (the text fixtures are
hand-written). Mesh: the 5-node, 2-tet "tiny" mesh used by every fixture,
tags [1, 2], plus one triangle that readers must skip."""
import base64, struct, zlib

P = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)]
T = [(0, 1, 2, 3), (1, 2, 3, 4)]
TRI = (0, 1, 2)
TAGS = [1, 2, 0]

# --- legacy VTK, BINARY (big-endian), classic cell layout
out = b"# vtk DataFile Version 3.0\ntiny binary\nBINARY\nDATASET UNSTRUCTURED_GRID\n"
out += b"POINTS 5 double\n" + b"".join(struct.pack(">3d", *p) for p in P) + b"\n"
cells = [4, *T[0], 4, *T[1], 3, *TRI]
out += b"CELLS 3 14\n" + struct.pack(">14i", *cells) + b"\n"
out += b"CELL_TYPES 3\n" + struct.pack(">3i", 10, 10, 5) + b"\n"
out += b"CELL_DATA 3\nSCALARS tag int 1\nLOOKUP_TABLE default\n" + struct.pack(">3i", *TAGS) + b"\n"
open("tiny_binary.vtk", "wb").write(out)


def arrays():
    pts = b"".join(struct.pack("<3d", *p) for p in P)
    conn = struct.pack("<11q", *T[0], *T[1], *TRI)
    offs = struct.pack("<3q", 4, 8, 11)
    types = bytes([10, 10, 5])
    tags = struct.pack("<3i", *TAGS)
    return [("Points", "Float64", 3, pts, "Points"), ("connectivity", "Int64", 1, conn, "Cells"),
            ("offsets", "Int64", 1, offs, "Cells"), ("types", "UInt8", 1, types, "Cells"),
            ("tag", "Int32", 1, tags, "CellData")]


def block(data, compress):
    """header (UInt64) + data, zlib in one block when compressed"""
    if not compress:
        return struct.pack("<Q", len(data)) + data
    c = zlib.compress(data)
    return struct.pack("<4Q", 1, len(data), len(data), len(c)) + c


def vtu_appended(name, encoding, compress):
    comp = ' compressor="vtkZLibDataCompressor"' if compress else ""
    head = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" '
            f'header_type="UInt64"{comp}>\n<UnstructuredGrid>\n<Piece NumberOfPoints="5" NumberOfCells="3">\n')
    sections = {"CellData": [], "Points": [], "Cells": []}
    blob = b""
    for arr_name, ty, nc, data, sec in arrays():
        b = block(data, compress)
        if encoding == "base64":
            b = base64.b64encode(b)
        sections[sec].append(f'<DataArray type="{ty}" Name="{arr_name}" NumberOfComponents="{nc}" '
                             f'format="appended" offset="{len(blob)}"/>\n')
        blob += b
    for sec in ["CellData", "Points", "Cells"]:
        head += f"<{sec}>\n" + "".join(sections[sec]) + f"</{sec}>\n"
    head += f'</Piece>\n</UnstructuredGrid>\n<AppendedData encoding="{encoding}">\n_'
    open(name, "wb").write(head.encode() + blob + b"\n</AppendedData>\n</VTKFile>\n")


vtu_appended("tiny_appended_raw.vtu", "raw", False)
vtu_appended("tiny_appended_raw_zlib.vtu", "raw", True)
vtu_appended("tiny_appended_base64.vtu", "base64", False)
