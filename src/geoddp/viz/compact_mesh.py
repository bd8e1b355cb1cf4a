"""Mesh files as compact binary geometry for the replay: what meshcat's viewer would build from the
file, read here once, quantised and sent as a three.js ``BufferGeometry``.

A robot's visual meshes are most of a replay's bytes: the UR5's seven COLLADA (DAE) files are
6.7 MB of XML text, the Panda's 10.5 MB, and meshcat embeds each as text (base64 in the HTML page,
one third more). The viewer turns that text into triangles with normals and one material per
primitive; this module does the same in Python and sends the result as typed arrays: positions
as uint16 in the mesh's bounding box (a step of 1/65535 of its largest side: 3 micrometres on a
0.2 m link). A flat-shaded mesh (each corner's normal its triangle's, as the Panda's and every
STL's) goes as separate triangles without normals, 18 bytes a triangle, the viewer computing the
same face normals; any other as an indexed geometry with int8 normals (a direction within 0.5 deg),
one vertex per distinct (position, normal) pair. Three to five times fewer bytes, the same drawing.

What the viewer draws is reproduced, not what a COLLADA reader might: meshcat merges the DAE scene
with each node's transform but without the file's ``<up_axis>`` rotation and ``<unit>`` scale (its
``merge_geometries`` reads the scene's stale matrix), and three.js's ColladaLoader splits a
``<polylist>`` quad as (0, 1, 3), (1, 2, 3) and a larger polygon as a fan. Each primitive's
material is the effect's (phong and blinn: MeshPhongMaterial, lambert: MeshLambertMaterial,
constant: MeshBasicMaterial) with its diffuse colour, specular colour and shininess, emission,
opacity and double-sidedness, as ColladaLoader (three.js r129, meshcat 0.3.2's) sets them. One
difference, on purpose: meshcat's merge of a file with several nodes loses every node that has
several materials (it nests their material list, which three.js then skips); here each primitive
keeps its material, so the UR5's dark joint housings are drawn.

A file this reader does not cover is left to meshcat as before (:func:`read_mesh` returns None):
images and textures, vertex colours, ``<polygons>`` and other primitive kinds than triangles and
polylists (lines are dropped, as meshcat drops them), ``<instance_node>``, controllers (skins),
``<lookat>``/``<skew>`` transforms, unbound material symbols, a file that does not parse, ASCII
STL, and OBJ files.
"""
from __future__ import annotations

import functools
import struct
import uuid
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import umsgpack

# meshcat's viewer (msgpack-lite) decodes these msgpack extension types into typed arrays.
_EXT = {np.dtype(np.int8): (0x11, "Int8Array"), np.dtype(np.uint8): (0x12, "Uint8Array"),
        np.dtype(np.uint16): (0x14, "Uint16Array"), np.dtype(np.uint32): (0x16, "Uint32Array"),
        np.dtype(np.float32): (0x17, "Float32Array")}
# three.js side constants
_FRONT, _DOUBLE = 0, 2
_MATERIALS = {"phong": "MeshPhongMaterial", "blinn": "MeshPhongMaterial", "lambert": "MeshLambertMaterial",
              "constant": "MeshBasicMaterial"}


@dataclass
class MeshData:
    """Triangles of a mesh file as the viewer draws them, in the file's units (metres for a URDF's
    meshes), before the URDF scale.

    Attributes:
        positions: (n, 3) vertex positions.
        normals: (n, 3) unit normals, or None (the viewer then computes them).
        triangles: (t, 3) vertex indices.
        groups: (start, count, material index) ranges of ``triangles`` (counted in triangles).
        materials: three.js material fields (``type``, ``color``, ...) of each group's material, or
            empty: the caller's material for the whole mesh.
    """

    positions: np.ndarray
    normals: np.ndarray | None
    triangles: np.ndarray
    groups: list[tuple[int, int, int]] = field(default_factory=list)
    materials: list[dict[str, Any]] = field(default_factory=list)

    @functools.cached_property
    def plain(self) -> "MeshData":
        """The same triangles as one group, to be drawn in one material given by the caller."""
        return MeshData(self.positions, self.normals, self.triangles, [(0, len(self.triangles), 0)], [])

    @functools.cached_property
    def packed(self) -> dict[str, Any]:
        """:func:`quantise` of this mesh, computed once."""
        return quantise(self)


class Unsupported(Exception):
    """The file uses something this reader leaves to meshcat (the message says what)."""


def read_mesh(path: str | Path) -> MeshData | None:
    """The triangles of a DAE or binary STL file as meshcat's viewer draws them, or None when the
    file is another kind or uses something this module leaves to meshcat (see the module
    docstring)."""
    ext = str(path).rsplit(".", 1)[-1].lower()
    try:
        if ext == "dae":
            return read_dae(path)
        if ext == "stl":
            return read_stl(path)
    except (Unsupported, OSError, ValueError, KeyError, IndexError, TypeError, AttributeError):
        # whatever this reader cannot take (or a malformed file) is meshcat's to load, as before
        return None
    return None


# ----------------------------------------------------------------------------- STL


def read_stl(path: str | Path) -> MeshData:
    """A binary STL file: its triangles with the file's facet normals (flat shading, as three.js's
    STLLoader draws them). Raises :class:`Unsupported` for an ASCII STL (or a file whose size does
    not match its triangle count)."""
    raw = Path(path).read_bytes()
    if len(raw) < 84:
        raise Unsupported("too short for a binary STL")
    (n,) = struct.unpack_from("<I", raw, 80)
    if len(raw) != 84 + 50 * n or n == 0:
        raise Unsupported("not a binary STL (ASCII, or truncated)")
    rec = np.frombuffer(raw, dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]), count=n, offset=84)
    corners = rec["v"].astype(np.float64).reshape(-1, 3)
    normals = np.repeat(rec["n"].astype(np.float64), 3, axis=0)
    bad = ~(np.linalg.norm(normals, axis=1) > 0)
    if bad.any():  # a zero facet normal: STLLoader keeps it (unlit); the face's own normal draws it
        tri = corners.reshape(-1, 3, 3)
        face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        normals[bad] = np.repeat(face, 3, axis=0)[bad]
    return _soup(corners, normals, [(0, n, 0)], [])


# ----------------------------------------------------------------------------- COLLADA


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _strip_namespaces(root: ET.Element) -> None:
    for el in root.iter():
        el.tag = _local(el.tag)


def _floats(text: str | None) -> np.ndarray:
    return np.array((text or "").split(), dtype=np.float64)


def _ref(url: str | None) -> str:
    if not url or not url.startswith("#"):
        raise Unsupported(f"external or missing reference {url!r}")
    return url[1:]


def _node_matrix(node: ET.Element) -> np.ndarray:
    """The node's transform: its <matrix>, <translate>, <rotate>, <scale> children multiplied in
    document order (COLLADA 1.4, 5.7)."""
    M = np.eye(4)
    for el in node:
        tag, v = el.tag, _floats(el.text)
        if tag == "matrix":
            T = v.reshape(4, 4)  # row-major in the file
        elif tag == "translate":
            T = np.eye(4)
            T[:3, 3] = v[:3]
        elif tag == "rotate":
            axis, angle = v[:3], np.radians(v[3])
            n = np.linalg.norm(axis)
            T = np.eye(4)
            if n > 0 and angle != 0.0:
                a = axis / n
                K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
                T[:3, :3] = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
        elif tag == "scale":
            T = np.diag([*v[:3], 1.0])
        elif tag in ("lookat", "skew"):
            raise Unsupported(f"<{tag}> transform")
        else:
            continue
        M = M @ T
    return M


def _color(el: ET.Element | None) -> np.ndarray | None:
    """The RGBA of a <diffuse>/<specular>/... parameter holding a <color>; None when absent.
    Raises Unsupported for a texture or a <param> reference."""
    if el is None:
        return None
    if el.find("texture") is not None:
        raise Unsupported("texture")
    c = el.find("color")
    if c is None:
        raise Unsupported(f"<{el.tag}> without a colour")
    v = _floats(c.text)
    return np.concatenate([v, [1.0] * (4 - v.size)])[:4] if v.size >= 3 else None


def _hex(rgb: np.ndarray) -> int:
    """The colour Color.fromArray(rgb) holds as 0xRRGGBB, 8 bits a channel truncated as three.js's
    Color.getHex does."""
    r, g, b = (int(255 * float(np.clip(c, 0.0, 1.0))) for c in rgb[:3])
    return (r << 16) | (g << 8) | b


def _material(effect: ET.Element) -> dict[str, Any]:
    """three.js material fields of a COLLADA effect, as ColladaLoader (r129) builds them."""
    tech = effect.find("profile_COMMON/technique")
    if tech is None:
        raise Unsupported("effect without profile_COMMON")
    shading = next((el for el in tech if el.tag in _MATERIALS), None)
    if shading is None:
        raise Unsupported("effect without phong, blinn, lambert or constant")
    kind = _MATERIALS[shading.tag]
    out: dict[str, Any] = {"type": kind}
    diffuse = _color(shading.find("diffuse"))
    if diffuse is not None:
        out["color"] = _hex(diffuse)
    if kind == "MeshPhongMaterial":
        specular = _color(shading.find("specular"))
        if specular is not None:
            out["specular"] = _hex(specular)
        shininess = shading.find("shininess/float")
        if shininess is not None and float(shininess.text):  # 0 keeps three.js's default (30), as ColladaLoader
            out["shininess"] = float(shininess.text)
    if kind != "MeshBasicMaterial":
        emission = _color(shading.find("emission"))
        if emission is not None:
            out["emissive"] = _hex(emission)
    transparent, transparency = shading.find("transparent"), shading.find("transparency/float")
    if transparent is not None or transparency is not None:
        t = 1.0 if transparency is None else float(transparency.text)
        mode = "A_ONE" if transparent is None else transparent.get("opaque", "A_ONE")
        color = np.ones(4) if transparent is None else _color(transparent)
        opacity = {"A_ONE": lambda c: c[3] * t, "RGB_ZERO": lambda c: 1 - c[0] * t,
                   "A_ZERO": lambda c: 1 - c[3] * t, "RGB_ONE": lambda c: c[0] * t}.get(mode)
        if opacity is None or color is None:
            raise Unsupported(f"transparency mode {mode!r}")
        out["opacity"] = float(opacity(color))
        if out["opacity"] < 1:
            out["transparent"] = True
    double = effect.find("profile_COMMON/extra/technique/double_sided")  # where ColladaLoader reads it
    out["side"] = _DOUBLE if double is not None and (double.text or "").strip() == "1" else _FRONT
    return out


def _source(sources: dict[str, ET.Element], sid: str) -> np.ndarray:
    """(count, 3) values of a <source> (its accessor's first three components)."""
    src = sources.get(sid)
    if src is None:
        raise Unsupported(f"source {sid!r} not found")
    arr = _floats(src.findtext("float_array"))
    acc = src.find("technique_common/accessor")
    stride = int(acc.get("stride", "1")) if acc is not None else 3
    offset = int(acc.get("offset", "0")) if acc is not None else 0
    count = int(acc.get("count")) if acc is not None and acc.get("count") else (arr.size - offset) // stride
    if stride < 3:
        raise Unsupported(f"source {sid!r} with stride {stride}")
    return arr[offset: offset + count * stride].reshape(count, stride)[:, :3]


def _primitive_corners(prim: ET.Element, vertices: dict[str, dict[str, str]], sources: dict[str, ET.Element]
                       ) -> tuple[np.ndarray, np.ndarray | None]:
    """(positions, normals) of the corners of a <triangles> or <polylist>, three per triangle."""
    inputs = {}
    stride = 0
    for inp in prim.findall("input"):
        sem, off = inp.get("semantic"), int(inp.get("offset", "0"))
        stride = max(stride, off + 1)
        if sem == "VERTEX":
            for vsem, vsrc in vertices[_ref(inp.get("source"))].items():
                inputs.setdefault(vsem, (off, vsrc))
        elif sem in ("NORMAL", "TEXCOORD", "COLOR", "TEXTANGENT", "TEXBINORMAL"):
            inputs.setdefault(sem, (off, _ref(inp.get("source"))))
        else:
            raise Unsupported(f"primitive input {sem!r}")
    if "COLOR" in inputs:
        raise Unsupported("vertex colours")
    if "POSITION" not in inputs:
        raise Unsupported("primitive without positions")
    p = np.array((prim.findtext("p") or "").split(), dtype=np.int64).reshape(-1, stride)
    if prim.tag == "polylist":
        vcount = np.array((prim.findtext("vcount") or "").split(), dtype=np.int64)
        if vcount.sum() != len(p) or (vcount < 3).any():
            raise Unsupported("polylist whose vcount does not match its indices")
        rows = []
        start = 0
        for vc in vcount:  # ColladaLoader's split: a quad as (0, 1, 3), (1, 2, 3), more as a fan
            if vc == 3:
                rows += [start, start + 1, start + 2]
            elif vc == 4:
                rows += [start, start + 1, start + 3, start + 1, start + 2, start + 3]
            else:
                for k in range(1, vc - 1):
                    rows += [start, start + k, start + k + 1]
            start += vc
        p = p[np.asarray(rows, dtype=np.int64)]
    elif len(p) % 3:
        raise Unsupported("triangles whose indices are not a multiple of 3")
    off, sid = inputs["POSITION"]
    positions = _source(sources, sid)[p[:, off]]
    normals = None
    if "NORMAL" in inputs:
        off, sid = inputs["NORMAL"]
        normals = _source(sources, sid)[p[:, off]]
    return positions, normals


def read_dae(path: str | Path) -> MeshData:
    """The triangles of a COLLADA file as meshcat's viewer draws them (see the module docstring).

    Raises:
        Unsupported: the file uses a feature left to meshcat (textures, vertex colours, ...) or is
            not a readable XML document.
        ValueError, KeyError, IndexError: malformed COLLADA (numbers, references, index counts).
    """
    try:
        root = ET.parse(str(path)).getroot()
    except (ET.ParseError, OSError) as exc:
        raise Unsupported(f"unreadable: {exc}") from None
    _strip_namespaces(root)
    if root.find(".//library_images/image") is not None or root.find(".//instance_controller") is not None:
        raise Unsupported("images or controllers")
    if root.find(".//instance_node") is not None or root.find(".//polygons") is not None:
        raise Unsupported("instance_node or polygons")
    effects = {e.get("id"): e for e in root.iterfind("library_effects/effect")}
    materials = {m.get("id"): _ref(m.find("instance_effect").get("url")) for m in root.iterfind("library_materials/material")}
    geometries = {g.get("id"): g for g in root.iterfind("library_geometries/geometry")}
    scene_url = root.find("scene/instance_visual_scene")
    scenes = {s.get("id"): s for s in root.iterfind("library_visual_scenes/visual_scene")}
    scene = scenes.get(_ref(scene_url.get("url"))) if scene_url is not None else next(iter(scenes.values()), None)
    if scene is None:
        raise Unsupported("no visual scene")

    pos_parts, nrm_parts, groups, mats = [], [], [], []
    mat_index: dict[str, int] = {}
    start = 0

    def visit(node: ET.Element, M: np.ndarray) -> None:
        nonlocal start
        M = M @ _node_matrix(node)
        N = np.linalg.inv(M[:3, :3]).T  # normals transform by the inverse transpose
        for inst in node.findall("instance_geometry"):
            geom = geometries.get(_ref(inst.get("url")))
            mesh = geom.find("mesh") if geom is not None else None
            if mesh is None:
                raise Unsupported("instance of a geometry that is not a <mesh>")
            bound = {im.get("symbol"): _ref(im.get("target"))
                     for im in inst.iterfind("bind_material/technique_common/instance_material")}
            sources = {s.get("id"): s for s in mesh.findall("source")}
            vertices = {v.get("id"): {i.get("semantic"): _ref(i.get("source")) for i in v.findall("input")}
                        for v in mesh.findall("vertices")}
            for prim in mesh:
                if prim.tag in ("lines", "linestrips"):
                    continue  # meshcat draws meshes only
                if prim.tag not in ("triangles", "polylist"):
                    if prim.tag in ("source", "vertices", "extra"):
                        continue
                    raise Unsupported(f"<{prim.tag}>")
                symbol = prim.get("material")
                if symbol is None:  # ColladaLoader's material when a primitive names none
                    mid, material = None, {"type": "MeshPhongMaterial"}
                elif symbol in bound and bound[symbol] in materials and materials[bound[symbol]] in effects:
                    mid, material = bound[symbol], None
                else:  # ColladaLoader draws it magenta: left to it
                    raise Unsupported(f"material symbol {symbol!r} not bound to an effect")
                P, Nn = _primitive_corners(prim, vertices, sources)
                if not len(P):
                    continue
                P = P @ M[:3, :3].T + M[:3, 3]
                pos_parts.append(P)
                if Nn is not None:
                    Nn = Nn @ N.T
                    Nn /= np.maximum(np.linalg.norm(Nn, axis=1, keepdims=True), 1e-300)
                nrm_parts.append(Nn)
                if mid not in mat_index:
                    mat_index[mid] = len(mats)
                    mats.append(material or _material(effects[materials[mid]]))
                groups.append((start, len(P) // 3, mat_index[mid]))
                start += len(P) // 3
        for child in node.findall("node"):
            visit(child, M)

    for node in scene.findall("node"):
        visit(node, np.eye(4))
    if not pos_parts:
        raise Unsupported("no triangles")
    corners = np.vstack(pos_parts)
    normals = None
    if any(n is not None for n in nrm_parts):
        # primitives without normals among others with: their face normals (what the viewer computes
        # for a geometry without normals; meshcat's own merge of such a file draws nothing)
        normals = np.vstack([n if n is not None else _face_normals(p) for p, n in zip(pos_parts, nrm_parts)])
    return _soup(corners, normals, groups, mats)


def _face_normals(corners: np.ndarray) -> np.ndarray:
    """(3t, 3) unit face normal of each corner's triangle (zero for a zero-area triangle)."""
    tri = corners.reshape(-1, 3, 3)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return np.repeat(n, 3, axis=0)


# ----------------------------------------------------------------------------- packing


def _soup(corners: np.ndarray, normals: np.ndarray | None, groups, materials) -> MeshData:
    """Corners (3 per triangle) as a mesh of separate triangles; :func:`quantise` shares the
    vertices (one per distinct quantised (position, normal) pair). Raises :class:`Unsupported` for
    non-finite coordinates (left to meshcat, whose drawing of them is its own)."""
    if not np.all(np.isfinite(corners)) or (normals is not None and not np.all(np.isfinite(normals))):
        raise Unsupported("non-finite coordinates")
    tri = np.arange(len(corners)).reshape(-1, 3)
    return MeshData(corners, normals, tri, list(groups), list(materials))


#: Largest angle (deg) between a corner's normal and its triangle's own normal for the triangle to
#: count as flat-shaded.
FLAT_DEG = 2.0
#: Largest share of a mesh's area on triangles that are not flat-shaded for the mesh to be sent
#: without normals: slivers whose file normals disagree with their (ill-defined) face normal, a
#: millionth of the area, cannot be seen (the Panda's links have 0 to 5 such of 12,000 to 21,000).
FLAT_AREA_SHARE = 1e-6


def flat_shaded(mesh: MeshData) -> bool:
    """True when the mesh has no normals or is drawn flat: each corner's normal is its triangle's
    face normal (within FLAT_DEG) on all but FLAT_AREA_SHARE of the area. The viewer's computed
    normals of a non-indexed geometry (three.js computeVertexNormals, which meshcat calls on a
    geometry without normals) then draw it the same."""
    if mesh.normals is None:
        return True
    P = np.asarray(mesh.positions, dtype=np.float64)[mesh.triangles]
    face = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    area = np.linalg.norm(face, axis=1)
    keep = area > 0
    if not keep.any():
        return True
    Nn = np.asarray(mesh.normals, dtype=np.float64)[mesh.triangles[keep]]
    cos = np.einsum("tj,tkj->tk", face[keep] / area[keep, None], Nn).min(axis=1)
    off = area[keep][cos < np.cos(np.radians(FLAT_DEG))].sum()
    return bool(off <= FLAT_AREA_SHARE * area[keep].sum())


def quantise(mesh: MeshData) -> dict[str, Any]:
    """The mesh as quantised typed arrays and the transform that restores its size.

    Positions become uint16 in the box [lo, lo + s]^3 (s the box's largest side: a step of
    s / 65535). A flat-shaded mesh (:func:`flat_shaded`) is sent as separate triangles without
    normals (6 bytes a corner, 18 a triangle; the viewer computes the face normals). Any other as
    an indexed geometry with int8 normals: one vertex per distinct quantised (position, normal)
    pair, in order of first use.

    Returns:
        ``position`` (n, 3) uint16, ``normal`` (n, 3) int8 or None, ``index`` (t, 3) uint16 or
        uint32 or None (separate triangles: vertices 3k, 3k+1, 3k+2), ``groups``, and ``matrix``
        (4, 4): the node transform mapping normalised positions (each coordinate in [0, 1]) to the
        file's coordinates: translation lo, uniform scale s.
    """
    P = np.asarray(mesh.positions, dtype=np.float64)[mesh.triangles.reshape(-1)]
    lo, hi = P.min(axis=0), P.max(axis=0)
    s = float(np.max(hi - lo)) or 1.0
    qp = np.round((P - lo) / s * 65535.0).astype(np.uint16)
    M = np.diag([s, s, s, 1.0])
    M[:3, 3] = lo
    if flat_shaded(mesh):
        return {"position": qp, "normal": None, "index": None, "groups": mesh.groups, "matrix": M}
    Nn = np.asarray(mesh.normals, dtype=np.float64)[mesh.triangles.reshape(-1)]
    qn = np.round(np.clip(Nn, -1.0, 1.0) * 127.0).astype(np.int8)
    key = np.hstack([qp, qn.view(np.uint8).astype(np.uint16)])
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    index = rank[inverse.reshape(-1)].reshape(-1, 3)
    idx_dtype = np.uint16 if order.size <= 65536 else np.uint32
    return {"position": qp[first[order]], "normal": qn[first[order]], "index": index.astype(idx_dtype),
            "groups": mesh.groups, "matrix": M}


def _typed(arr: np.ndarray, item_size: int, normalized: bool) -> dict[str, Any]:
    code, name = _EXT[arr.dtype]
    return {"itemSize": item_size, "type": name, "array": umsgpack.Ext(code, np.ascontiguousarray(arr).tobytes()),
            "normalized": normalized}


class CompactMeshObject:
    """A meshcat ``set_object`` command drawing a :class:`MeshData` as one three.js ``Mesh`` of a
    quantised ``BufferGeometry`` (sent with ``window.send``, like Pinocchio's DAE element).

    Args:
        mesh: the triangles.
        material: three.js material fields for the whole mesh (e.g. the URDF colour or the ghost's
            translucent blue), or None: the file's own materials, one per group.
    """

    def __init__(self, mesh: MeshData, material: dict[str, Any] | None = None) -> None:
        self.mesh = mesh
        self.material = material
        self.path = None

    def lower(self) -> dict[str, Any]:
        q = self.mesh.packed
        geometry_id = str(uuid.uuid1())
        attributes = {"position": _typed(q["position"], 3, True)}
        if q["normal"] is not None:
            attributes["normal"] = _typed(q["normal"], 3, True)
        # three.js (r129) would compute the bounding sphere from the raw uint16 values, 65535 times
        # too large and off-centre, and cull the mesh whenever the camera sits outside that sphere:
        # the sphere of the normalised positions the shader draws is given instead
        unit = q["position"].astype(np.float64) / 65535.0
        centre = 0.5 * (unit.min(axis=0) + unit.max(axis=0))
        radius = float(np.sqrt(np.max(np.sum((unit - centre) ** 2, axis=1))))
        data: dict[str, Any] = {"attributes": attributes,
                                "boundingSphere": {"center": [float(c) for c in centre], "radius": radius}}
        if q["index"] is not None:
            data["index"] = _typed(q["index"].reshape(-1), 1, False)
        own = self.material is None
        mats = [dict(m) for m in self.mesh.materials] if own else [dict(self.material)]
        for m in mats:
            m["uuid"] = str(uuid.uuid1())
        if own and len(mats) > 1:
            data["groups"] = [{"start": 3 * a, "count": 3 * n, "materialIndex": i} for a, n, i in q["groups"]]
            material: Any = [m["uuid"] for m in mats]
        else:
            material = mats[0]["uuid"]
        return {
            "type": "set_object",
            "path": self.path.lower() if self.path is not None else "",
            "object": {
                "metadata": {"version": 4.5, "type": "Object"},
                "geometries": [{"uuid": geometry_id, "type": "BufferGeometry", "data": data}],
                "materials": mats,
                "object": {"uuid": str(uuid.uuid1()), "type": "Mesh", "geometry": geometry_id, "material": material,
                           "matrix": [float(x) for x in q["matrix"].T.reshape(-1)]},
            },
        }


def mesh_box(mesh: MeshData) -> tuple[np.ndarray, np.ndarray]:
    """(lower (3,), upper (3,)) corners of the box of the vertices the triangles use."""
    P = np.asarray(mesh.positions)[np.unique(mesh.triangles)]
    return P.min(axis=0), P.max(axis=0)


__all__ = ["CompactMeshObject", "MeshData", "Unsupported", "mesh_box", "quantise", "read_dae", "read_mesh", "read_stl"]
