"""URDF input checks: encodings, joint axes, masses and inertias, by name.

:func:`build_checked_model` is the one entry the model builders call: it reads the file
(:func:`read_urdf_text`: the encoding a byte-order mark or its XML declaration names, else
UTF-8; undecodable bytes, unknown encodings and entity declarations refused by name, with the
file), checks the text (:func:`check_urdf_text`: every moving joint's axis finite and
non-zero, every inertial finite), builds the Pinocchio model from that text with urdfdom's own
stderr lines captured and folded into the error message, and checks the model
(:func:`check_model`: no moving body without mass or with a singular inertia, seen as a joint
whose block of the joint-space mass matrix M(q0) is not positive definite).
:func:`build_urdf_model` does the same without the mass check, for a satellite's URDF (whose
inertia the scene gives); :func:`read_xml_text` reads an SRDF by the same rules.

Imports only pinocchio, numpy and :mod:`geoddp.validate` (floor 0).
"""
from __future__ import annotations

import codecs
import math
import os
import re
import tempfile
import threading
import xml.etree.ElementTree as ET
from collections import OrderedDict
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import numpy as np
import pinocchio as pin

from ..validate import InputError

__all__ = ["read_xml_text", "read_urdf_text", "parse_xml", "check_urdf_text", "check_model", "build_checked_model",
           "build_urdf_model", "captured_stderr"]

_DECL = re.compile(rb"""^\s*<\?xml[^>]*encoding\s*=\s*["']([A-Za-z0-9._-]+)["']""")
# Byte-order marks, longest first (UTF-32 LE starts with UTF-16 LE's mark; the codec drops the
# mark), then UTF-16 without one, known by its first characters "<?" (XML 1.0, appendix F.1).
_BOMS = ((codecs.BOM_UTF32_LE, "utf-32"), (codecs.BOM_UTF32_BE, "utf-32"), (codecs.BOM_UTF8, "utf-8-sig"),
         (codecs.BOM_UTF16_LE, "utf-16"), (codecs.BOM_UTF16_BE, "utf-16"), (b"<\0?\0", "utf-16-le"),
         (b"\0<\0?", "utf-16-be"))
_TEXT_DECL = re.compile(r"""^\s*<\?xml[^>]*?(\s+encoding\s*=\s*["'])([^"']*)["']""")
_ENTITY = re.compile(r"<!ENTITY\b")
_COMMENT = re.compile(r"<!--.*?-->", re.S)
_MOVING = ("revolute", "continuous", "prismatic", "planar")
# Largest URDF or SRDF read: the largest of example-robot-data's (TIAGo dual) is 0.2 MiB. A file
# is held several times over (bytes, text, Pinocchio's copy, the Result's urdf_xml and its JSON:
# a 200 MiB URDF took 1.1 GB and 18 s), so a huge one is refused by name rather than let run
# the machine out of memory.
MAX_XML_BYTES = 64 << 20
MAX_XML_DEPTH = 64  # element nesting; URDFs and SRDFs nest 3-6 levels (gazebo extensions included)


def read_xml_text(path: str | Path, name: str = "urdf", kind: str = "URDF") -> str:
    """The text of an XML file (a URDF or an SRDF), decoded as XML says: a byte-order mark
    (UTF-8, UTF-16, UTF-32) decides; else the encoding the XML declaration names (e.g.
    ``ISO-8859-1``, which Pinocchio then gets as UTF-8 text with the declaration's encoding
    removed); else UTF-8.

    Raises:
        InputError: naming ``name`` and the file: unreadable, not valid text in its encoding
            (binary garbage, Latin-1 bytes without a declaration), an unknown or non-text
            encoding in the declaration, or entity declarations (``<!ENTITY``), which the
            parsers Pinocchio uses (urdfdom's TinyXML2, Boost's property tree) do not expand:
            what they read would differ from what the checks here read.
    """
    try:
        size = Path(path).stat().st_size
        if size > MAX_XML_BYTES:
            raise InputError(name, f"{path}: expected a {kind} file of at most {MAX_XML_BYTES >> 20} MiB, got "
                             f"{size / 2**20:.0f} MiB (meshes belong in mesh files)")
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise InputError(name, f"expected a readable {kind} file, got {str(path)!r} ({exc.strerror or exc})") from None
    bom = next((enc for mark, enc in _BOMS if raw.startswith(mark)), None)
    m = None if bom else _DECL.match(raw[:200])
    enc = bom or (m.group(1).decode("ascii") if m else "utf-8")
    try:
        text = raw.decode(enc)
    except LookupError:  # not a codec, or not a text codec ("rot13", "bz2")
        raise InputError(name, f"{path}: unknown encoding {enc!r} in the XML declaration (expected a text encoding "
                         "such as UTF-8 or ISO-8859-1)") from None
    except UnicodeError as exc:
        where = (f" (byte {exc.start}: {raw[exc.start:exc.start + 1]!r})"
                 if isinstance(exc, UnicodeDecodeError) else "")
        label = "UTF-8" if enc.lower().replace("_", "-") in ("utf-8", "utf8") else enc
        raise InputError(name, f"{path}: not valid {label} text{where}; declare the file's encoding in "
                         "<?xml ... encoding=\"...\"?> or save it as UTF-8") from None
    text = text.lstrip("\ufeff")
    try:
        text.encode("utf-8")  # what Pinocchio is given; a lone surrogate (from "unicode_escape") is not text
    except UnicodeEncodeError as exc:
        raise InputError(name, f"{path}: not valid {enc} text (character {exc.start} is a lone surrogate); save it as "
                         "UTF-8") from None
    if _ENTITY.search(_COMMENT.sub("", text)):
        raise InputError(name, f"{path}: declares XML entities (<!ENTITY ...>), which Pinocchio's {kind} parser does "
                         "not expand; write their values out")
    declared = _TEXT_DECL.match(text)
    if declared is None or (_utf8(enc) and _utf8(declared.group(2))):
        return text  # as in the file: the Result's urdf_xml stays the file's text
    # The declaration no longer holds once decoded (Pinocchio reads UTF-8 strings), or never held
    # (a UTF-8 byte-order mark before encoding="UTF-16": expat then refuses the UTF-8 bytes).
    return text[:declared.start(2) - len(declared.group(1))] + text[declared.end(2) + 1:]


def _utf8(encoding: str) -> bool:
    try:
        return codecs.lookup(encoding).name in ("utf-8", "utf-8-sig")
    except LookupError:
        return False


def read_urdf_text(path: str | Path, name: str = "urdf") -> str:
    """The text of a URDF file (:func:`read_xml_text`). InputError naming ``name`` and the file."""
    return read_xml_text(path, name, "URDF")


def parse_xml(text: str, name: str, where: str = "") -> ET.Element:
    """The root element of ``text``; InputError naming ``name`` (``where`` prefixes the message)
    if it is not well-formed XML or nests elements more than :data:`MAX_XML_DEPTH` levels deep.
    Boost's property tree (Pinocchio's SRDF reader) recurses once per level: a file nested some
    10^5 levels deep crashed the process."""
    try:
        root = ET.fromstring(text.encode("utf-8"))
    except (ET.ParseError, ValueError) as exc:  # ValueError: expat's own refusals (a multi-byte encoding)
        raise InputError(name, f"{where}not well-formed XML ({exc})") from None
    stack = [(root, 1)]
    while stack:  # iterative: the tree may be as deep as the file says
        node, depth = stack.pop()
        if depth > MAX_XML_DEPTH:
            raise InputError(name, f"{where}expected XML elements nested at most {MAX_XML_DEPTH} levels deep, got "
                             f"deeper (<{node.tag}>)")
        stack.extend((child, depth + 1) for child in node)
    return root


def _floats(text: str | None, n: int) -> list[float] | None:
    if text is None:
        return None
    try:
        vals = [float(t) for t in text.split()]
    except ValueError:
        return []
    return vals if len(vals) == n else []


def check_urdf_text(text: str, name: str = "urdf", path: str | Path | None = None) -> None:
    """Refuse, by joint or link name: a moving joint whose axis is not 3 finite numbers or is zero,
    and an inertial (mass, inertia) that is not finite or negative; text that is not well-formed
    XML (NUL bytes, a truncated file). InputError naming ``name`` (and ``path`` when given)."""
    where = f"{path}: " if path is not None else ""
    root = parse_xml(text, name, where)
    for j in root.iter("joint"):
        jname, jtype = j.get("name", "?"), j.get("type", "")
        axis = j.find("axis")
        if jtype not in _MOVING or axis is None:
            continue
        xyz = _floats(axis.get("xyz"), 3)
        if xyz is None:
            continue  # URDF default (1, 0, 0)
        if not xyz or not all(math.isfinite(x) for x in xyz):
            raise InputError(name, f"{where}joint {jname!r}: axis xyz = {axis.get('xyz')!r}, expected 3 finite numbers")
        if math.sqrt(sum(x * x for x in xyz)) < 1e-12:
            raise InputError(name, f"{where}joint {jname!r}: axis xyz = {axis.get('xyz')!r} is zero; a {jtype} joint "
                             "needs a direction")
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        lname = link.get("name", "?")
        mass = inertial.find("mass")
        if mass is not None:
            try:
                mv = float(mass.get("value", "nan"))
            except ValueError:
                mv = float("nan")
            if not math.isfinite(mv) or mv < 0:
                raise InputError(name, f"{where}link {lname!r}: mass {mass.get('value')!r}, expected a finite number "
                                 ">= 0")
        inertia = inertial.find("inertia")
        if inertia is not None:
            for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
                try:
                    val = float(inertia.get(key, "0"))
                except ValueError:
                    val = float("nan")
                if not math.isfinite(val):
                    raise InputError(name, f"{where}link {lname!r}: inertia {key} = {inertia.get(key)!r}, expected a "
                                     "finite number")


def _body_of(model: pin.Model, joint: int) -> str:
    for f in model.frames:
        if f.parentJoint == joint and f.type == pin.FrameType.BODY:
            return f.name
    return model.names[joint]


def check_model(model: pin.Model, name: str = "urdf") -> None:
    """Refuse a model whose motion is undefined, naming the joint and the link it moves:
    a massless moving body or a singular inertia shows as a joint whose diagonal block of the
    joint-space mass matrix M(q0) (q0 = neutral) is not positive definite (Cholesky)."""
    for i in range(1, model.njoints):
        inert = model.inertias[i]
        if not (math.isfinite(inert.mass) and np.all(np.isfinite(inert.inertia)) and np.all(np.isfinite(inert.lever))):
            raise InputError(name, f"link {_body_of(model, i)!r} (joint {model.names[i]!r}): non-finite inertia")
    data = model.createData()
    M = pin.crba(model, data, pin.neutral(model))
    M = np.triu(M) + np.triu(M, 1).T
    scale = max(1.0, float(np.max(np.abs(np.diag(M))))) if M.size else 1.0
    for i in range(1, model.njoints):
        j = model.joints[i]
        if j.nv == 0:
            continue
        blk = M[j.idx_v:j.idx_v + j.nv, j.idx_v:j.idx_v + j.nv]
        ok = True
        try:
            L = np.linalg.cholesky(blk)
            ok = float(np.min(np.diag(L))) ** 2 > 1e-14 * scale
        except np.linalg.LinAlgError:
            ok = False
        if not ok:
            mass = sum(model.inertias[k].mass for k in range(i, model.njoints) if _in_subtree(model, k, i))
            what = ("moves no mass (massless body)" if mass <= 0 else
                    "sees a singular inertia (zero inertia about a direction it moves)")
            raise InputError(name, f"joint {model.names[i]!r} (link {_body_of(model, i)!r}) {what}: its block of "
                             "the mass matrix M(q) is not positive definite; give the link a mass and a positive "
                             "definite inertia")


def _in_subtree(model: pin.Model, k: int, root: int) -> bool:
    while k > 0:
        if k == root:
            return True
        k = model.parents[k]
    return False


@contextmanager
def captured_stderr() -> Iterator[list[str]]:
    """Redirect file descriptor 2 (where urdfdom's C++ code writes) into a temporary file for
    the duration of the block; the lines are appended to the yielded list on exit."""
    lines: list[str] = []
    try:
        saved = os.dup(2)
    except OSError:
        yield lines
        return
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            lines.extend(t for t in tmp.read().decode("utf-8", "replace").splitlines() if t.strip())


# Models built and checked in this process, by (root joint, URDF text): a sweep or a loop over
# scenes builds the same robot for every case, twice (the scene reader builds it to check names
# against it, the builder for the problem), and building and checking is 1-3 ms where a solve of
# the UR5 takes 4 (benchmarks/case_overhead.py). The key is the text itself, so an edited file is
# a new model; only models that passed every check are kept; callers get copies (they set the
# gravity, reduce or edit them).
_BUILT: OrderedDict[tuple[str, str], pin.Model] = OrderedDict()
_BUILT_MAX = 16
_BUILT_LOCK = threading.Lock()
# root joints that the name of their type determines ("" = none, a fixed root)
_UNPARAMETRISED = ("", "JointModelFreeFlyer", "JointModelSpherical", "JointModelSphericalZYX", "JointModelPlanar",
                   "JointModelTranslation")


def build_checked_model(path: str | Path, root_joint: object | None = None, name: str = "urdf") -> pin.Model:
    """Read, check and build a URDF model (see the module docstring). InputError naming ``name``.

    The model is a new copy on every call; a URDF text already built and checked in this
    process (with the same root joint) is copied from the one built then, not built again.
    """
    text = read_urdf_text(path, name)
    kind = "" if root_joint is None else getattr(root_joint, "shortname", lambda: "?")()
    if kind not in _UNPARAMETRISED:  # a root joint with parameters (an axis, a pitch), or not a joint: built each time
        return _build_checked(text, path, root_joint, name)
    key = (kind, text)
    with _BUILT_LOCK:
        built = _BUILT.get(key)
        if built is not None:
            _BUILT.move_to_end(key)
            return pin.Model(built)
    model = _build_checked(text, path, root_joint, name)
    with _BUILT_LOCK:
        _BUILT[key] = pin.Model(model)
        while len(_BUILT) > _BUILT_MAX:
            _BUILT.popitem(last=False)
    return model


def build_urdf_model(path: str | Path, root_joint: object | None = None, name: str = "urdf") -> pin.Model:
    """Read, check (:func:`read_urdf_text`, :func:`check_urdf_text`) and build a URDF model, with
    urdfdom's stderr folded into the error, but without :func:`check_model`: for callers that
    replace the inertias (a satellite's URDF gives only its shape). InputError naming ``name``."""
    return _build(read_urdf_text(path, name), path, root_joint, name)


def _build_checked(text: str, path: str | Path, root_joint: object | None, name: str) -> pin.Model:
    model = _build(text, path, root_joint, name)
    try:
        check_model(model, name)
    except InputError as exc:
        raise InputError(name, f"{path}: {exc.detail}") from None
    return model


def _build(text: str, path: str | Path, root_joint: object | None, name: str) -> pin.Model:
    check_urdf_text(text, name, path)
    with captured_stderr() as lines:
        try:
            model = pin.buildModelFromXML(text) if root_joint is None else pin.buildModelFromXML(text, root_joint)
        except (ValueError, RuntimeError) as exc:
            failure = exc
        else:
            failure = None
    if failure is not None:
        said = "; ".join(lines[-3:])
        raise InputError(name, f"expected a valid URDF model, got {str(path)!r} ({failure})"
                         + (f"; urdfdom: {said}" if said else ""))
    return model
