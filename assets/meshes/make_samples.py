#!/usr/bin/env python3
"""Writes the small sample meshes in this folder (run from anywhere).

One box [0,2]x[0,1]x[0,0.5] (volume 1) split into 6 Kuhn tetrahedra, as
tet4 (8 nodes) and tet10 (27 nodes), in every format incise reads, each in
that format's own tet10 node order. Independent of the C++ writers on
purpose, so the reader tests cannot be fooled by a matching writer bug.
Files also carry things readers must skip: surface elements, sections,
attributes, comments, sparse tags, an unused node.
"""
import os

HERE = os.path.dirname(os.path.abspath(__file__))
SIZE = (2.0, 1.0, 0.5)
EDGES = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]  # ours = VTK = Abaqus


def det3(a, b, c):
    return (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0]))


def box():
    corners = [(i, j, k) for k in (0, 1) for j in (0, 1) for i in (0, 1)]
    X = [tuple(c[d] * SIZE[d] for d in range(3)) for c in corners]
    idx = {c: n for n, c in enumerate(corners)}
    tets = []
    for p in [(0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)]:
        c, v = [0, 0, 0], [idx[(0, 0, 0)]]
        for a in p:
            c[a] = 1
            v.append(idx[tuple(c)])
        x = [X[n] for n in v]
        d = [tuple(x[i][k] - x[0][k] for k in range(3)) for i in (1, 2, 3)]
        if det3(*d) < 0:
            v[2], v[3] = v[3], v[2]
        tets.append(v)
    return X, tets


def tet10(X, tets):
    X = list(X)
    mid = {}
    out = []
    for t in tets:
        m = []
        for a, b in EDGES:
            key = (min(t[a], t[b]), max(t[a], t[b]))
            if key not in mid:
                mid[key] = len(X)
                X.append(tuple(0.5 * (X[t[a]][k] + X[t[b]][k]) for k in range(3)))
            m.append(mid[key])
        out.append(t + m)
    return X, out


def gmsh_order(t):  # Gmsh: 8=(3,2), 9=(3,1)
    return t if len(t) == 4 else t[:8] + [t[9], t[8]]


def tetgen_order(t):  # TetGen 1.5 -o2: (2,3) (0,3) (0,1) (1,2) (1,3) (0,2)
    return t if len(t) == 4 else t[:4] + [t[9], t[7], t[4], t[5], t[8], t[6]]


def fmt(x):
    return " ".join(repr(float(v)) for v in x)


def write(name, text):
    with open(os.path.join(HERE, name), "w") as f:
        f.write(text)


def msh22(name, X, tets, tag):
    etype = 4 if len(tets[0]) == 4 else 11
    s = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"
    s += '$PhysicalNames\n1\n3 1 "tissue"\n$EndPhysicalNames\n'
    extra = 1 if tag(0) != 1 else 0  # the sparse variant gets an unused node
    s += "$Nodes\n%d\n" % (len(X) + extra)
    for n in reversed(range(len(X))):  # file order != tag order
        s += "%d %s\n" % (tag(n), fmt(X[n]))
    if extra:
        s += "999 9 9 9\n"
    s += "$EndNodes\n$Elements\n%d\n" % (len(tets) + 1 + extra)
    eid = 100
    s += "%d 2 2 0 1 %d %d %d\n" % (eid, tag(0), tag(1), tag(2))  # a triangle, skipped
    if extra:
        eid += 1
        s += "%d 15 2 0 9 999\n" % eid  # a point element on the unused node
    for t in tets:
        eid += 1
        s += "%d %d 2 1 1 %s\n" % (eid, etype, " ".join(str(tag(n)) for n in gmsh_order(t)))
    s += "$EndElements\n"
    write(name, s)


def msh41(name, X, tets, tag):
    etype = 4 if len(tets[0]) == 4 else 11
    tags = [tag(n) for n in range(len(X))]
    s = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"
    s += "$Entities\n0 0 1 1\n1 0 0 0 2 1 0 0 0\n1 0 0 0 2 1 0.5 0 1 1\n$EndEntities\n"
    s += "$Nodes\n2 %d %d %d\n" % (len(X), min(tags), max(tags))
    blocks = [(2, 1, list(range(0, 3))), (3, 1, list(range(3, len(X))))]
    for dim, ent, ns in blocks:
        s += "%d %d 0 %d\n" % (dim, ent, len(ns))
        s += "".join("%d\n" % tags[n] for n in ns)
        s += "".join("%s\n" % fmt(X[n]) for n in ns)
    s += "$EndNodes\n"
    s += "$Elements\n2 %d 1 %d\n" % (len(tets) + 1, len(tets) + 1)
    s += "2 1 2 1\n1 %d %d %d\n" % (tags[0], tags[1], tags[2])
    s += "3 1 %d %d\n" % (etype, len(tets))
    for e, t in enumerate(tets):
        s += "%d %s\n" % (e + 2, " ".join(str(tags[n]) for n in gmsh_order(t)))
    s += "$EndElements\n"
    write(name, s)


def vtk_classic(name, X, tets):
    ctype = 10 if len(tets[0]) == 4 else 24
    s = "# vtk DataFile Version 3.0\nsample box\nASCII\nDATASET UNSTRUCTURED_GRID\n"
    s += "POINTS %d double\n" % len(X)
    s += "".join(fmt(x) + "\n" for x in X)
    size = sum(len(t) + 1 for t in tets) + 4
    s += "CELLS %d %d\n3 0 1 2\n" % (len(tets) + 1, size)
    s += "".join("%d %s\n" % (len(t), " ".join(map(str, t))) for t in tets)
    s += "CELL_TYPES %d\n5\n" % (len(tets) + 1) + "".join("%d\n" % ctype for _ in tets)
    s += "POINT_DATA %d\nSCALARS id int 1\nLOOKUP_TABLE default\n" % len(X)
    s += "".join("%d\n" % n for n in range(len(X)))
    write(name, s)


def vtk51(name, X, tets):
    ctype = 10 if len(tets[0]) == 4 else 24
    s = "# vtk DataFile Version 5.1\nsample box, 5.1 layout\nASCII\nDATASET UNSTRUCTURED_GRID\n"
    s += "POINTS %d double\n" % len(X)
    s += "".join(fmt(x) + "\n" for x in X)
    s += "METADATA\nINFORMATION 0\n\n"
    offs, conn = [0], []
    for t in tets:
        conn += t
        offs.append(len(conn))
    s += "CELLS %d %d\nOFFSETS vtktypeint64\n%s\n" % (len(offs), len(conn), " ".join(map(str, offs)))
    s += "CONNECTIVITY vtktypeint64\n%s\n" % " ".join(map(str, conn))
    s += "CELL_TYPES %d\n" % len(tets) + "".join("%d\n" % ctype for _ in tets)
    write(name, s)


def vtu(name, X, tets):
    ctype = 10 if len(tets[0]) == 4 else 24
    conn, offs = [], []
    for t in tets:
        conn += t
        offs.append(len(conn))
    conn += [0, 1, 2]  # a triangle, skipped
    offs.append(len(conn))
    s = '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">\n'
    s += '<UnstructuredGrid>\n<Piece NumberOfPoints="%d" NumberOfCells="%d">\n' % (len(X), len(tets) + 1)
    s += '<PointData><DataArray type="Float64" Name="T" format="ascii">%s</DataArray></PointData>\n' % (
        " ".join("1" for _ in X))
    s += '<Points>\n<DataArray type="Float64" Name="Points" NumberOfComponents="3" format="ascii">\n'
    s += "".join(fmt(x) + "\n" for x in X)
    s += "</DataArray>\n</Points>\n<Cells>\n"
    s += '<DataArray type="Int64" Name="connectivity" format="ascii">\n%s\n</DataArray>\n' % " ".join(map(str, conn))
    s += "<DataArray type='Int64' Name='offsets' format='ascii'>%s</DataArray>\n" % " ".join(map(str, offs))
    s += '<DataArray type="UInt8" Name="types" format="ascii">%s 5</DataArray>\n' % " ".join(
        str(ctype) for _ in tets)
    s += "</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n"
    write(name, s)


def tetgen(stem, X, tets, base):
    s = "# sample box, %d-based, one attribute and a boundary marker\n%d 3 1 1\n" % (base, len(X))
    s += "".join("%d  %s  0.5  %d\n" % (n + base, fmt(x), n % 2) for n, x in enumerate(X))
    s += "# Generated by make_samples.py\n"
    write(stem + ".node", s)
    s = "%d %d 1\n" % (len(tets), len(tets[0]))
    s += "".join("%d  %s  7\n" % (e + base, " ".join(str(n + base) for n in tetgen_order(t)))
                 for e, t in enumerate(tets))
    write(stem + ".ele", s)


def inp(name, X, tets):
    etype = "C3D4" if len(tets[0]) == 4 else "C3D10"
    s = "*Heading\n sample box\n** node numbers are 1-based\n*node, nset=NALL\n"
    s += "".join("%d, %s\n" % (n + 1, ", ".join(repr(v) for v in x)) for n, x in enumerate(X))
    s += "*ELEMENT, TYPE=S3, ELSET=SKIN\n1, 1, 2, 3\n"
    s += "*Element, type=%s, elset=EALL\n" % etype
    for e, t in enumerate(tets):
        ids = [str(n + 1) for n in t]
        if len(t) == 10:  # as CalculiX writes: the element spans two lines
            s += "%d, %s,\n%s\n" % (e + 10, ", ".join(ids[:8]), ", ".join(ids[8:]))
        else:
            s += "%d, %s\n" % (e + 10, ", ".join(ids))
    s += "*Elset, elset=E1\n10\n*MATERIAL, NAME=tissue\n*ELASTIC\n3000., 0.45\n"
    write(name, s)


def main():
    X4, T4 = box()
    X10, T10 = tet10(X4, T4)
    for tag_name, X, T in [("tet4", X4, T4), ("tet10", X10, T10)]:
        msh22("box_%s_v22.msh" % tag_name, X, T, lambda n: 1 + n)
        msh41("box_%s_v41.msh" % tag_name, X, T, lambda n: 10 + 7 * n)
        vtu("box_%s.vtu" % tag_name, X, T)
        inp("box_%s.inp" % tag_name, X, T)
    msh22("box_tet4_sparse_v22.msh", X4, T4, lambda n: 5 + 3 * n * n)
    vtk_classic("box_tet4.vtk", X4, T4)
    vtk51("box_tet10.vtk", X10, T10)
    vtk51("box_tet4_v51.vtk", X4, T4)
    vtk_classic("box_tet10_classic.vtk", X10, T10)
    tetgen("box_tet4", X4, T4, 1)
    tetgen("box_tet10", X10, T10, 0)


if __name__ == "__main__":
    main()
