"""Bad files end as bad input, never as internal errors: every class of undecodable, malformed,
nested-too-deep or oversized URDF, SRDF, scene file and sweep file makes the CLI exit 2 with one
line on stderr that names the offending file, and no traceback. The encodings XML allows (a
declared ISO-8859-1, a byte-order mark) are decoded and solve as the UTF-8 file does.

The CLI runs in this process (``geoddp.cli.main``); ``capfd`` sees file descriptor 2 too, where
urdfdom and Pinocchio print.
"""
from __future__ import annotations

import codecs
import json
from pathlib import Path

import pytest

from geoddp.cli import main
from geoddp.data import scene_path, urdf_path

QUAD_URDF = urdf_path("quadrotor.urdf").read_text(encoding="utf-8")
SAT_URDF = urdf_path("satellite.urdf").read_text(encoding="utf-8")
QUAD_SCENE = (scene_path("quadrotor").read_text(encoding="utf-8")
              .replace('urdf = "quadrotor.urdf"', 'urdf = "m.urdf"').replace("steps = 150", "steps = 5"))
SAT_SCENE = scene_path("satellite_paper").read_text(encoding="utf-8")
assert 'urdf = "m.urdf"' in QUAD_SCENE and "steps = 5" in QUAD_SCENE

ENTITY_BOMB = ('<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa">'
               + "".join(f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">' for i in range(9))
               + "]>\n" + QUAD_URDF.split("?>", 1)[1].replace('name="quadrotor"', 'name="&j;"', 1))
LATIN1 = QUAD_URDF.replace("Quadrotor scene:", "Quadrotor scene (\u00e9t\u00e9):", 1)
DECLARED = LATIN1.replace('<?xml version="1.0"?>', '<?xml version="1.0" encoding="ISO-8859-1"?>', 1)
assert LATIN1 != QUAD_URDF and DECLARED != LATIN1


def run_cli(capfd, *argv: str) -> tuple[int, str, list[str]]:
    """(exit code, stdout, stderr lines) of ``geoddp ARGV`` run here."""
    capfd.readouterr()
    rc = main(list(argv))
    out, err = capfd.readouterr()
    return rc, out, [ln for ln in err.splitlines() if ln.strip()]


def refused(capfd, named: Path, *argv: str, words: tuple[str, ...] = ()) -> str:
    """Exit 2, exactly one stderr line (geoddp's), naming ``named``; no traceback anywhere."""
    rc, out, err = run_cli(capfd, *argv)
    assert rc == 2, (rc, out, err)
    assert len(err) == 1 and err[0].startswith("geoddp: error: "), err
    assert str(named) in err[0], err[0]
    assert "Traceback" not in out and "internal error" not in err[0]
    for w in words:
        assert w in err[0], err[0]
    return err[0]


def quad_scene(folder: Path, urdf: bytes, extra_model: str = "", initial: str | None = None) -> tuple[Path, Path]:
    folder.mkdir(exist_ok=True)
    (folder / "m.urdf").write_bytes(urdf)
    text = QUAD_SCENE.replace('urdf = "m.urdf"', 'urdf = "m.urdf"' + extra_model)
    if initial is not None:
        text = text.replace("translation = [0.0, 0.0, 1.0]", initial)
    (folder / "scene.toml").write_text(text, encoding="utf-8")
    return folder / "scene.toml", folder / "m.urdf"


def solved_cost(capfd, scene: Path) -> float:
    out = scene.parent / "out.json"
    rc, stdout, err = run_cli(capfd, "run", str(scene), "--quiet", "--json", str(out))
    assert rc in (0, 1) and err == [], (rc, err)
    return json.loads(out.read_text())["cost"]


@pytest.fixture(scope="module")
def quad_cost(tmp_path_factory) -> float:
    """J* of the 5-step quadrotor with its URDF as shipped (UTF-8)."""
    from geoddp import solve_scene
    from geoddp.scene import load_scene

    scene, _ = quad_scene(tmp_path_factory.mktemp("good"), QUAD_URDF.encode("utf-8"))
    return solve_scene(load_scene(scene), verbose=False).cost


# ------------------------------------------------------------------ URDF (multibody scene)

URDF_CASES = {
    "binary garbage": (bytes(range(256)) * 8, ("not valid UTF-8 text (byte ",)),
    "Latin-1 bytes, undeclared": (LATIN1.encode("latin-1"), ("not valid UTF-8 text", "declare the file's encoding")),
    "Latin-1 bytes declared UTF-8": (LATIN1.replace('<?xml version="1.0"?>', '<?xml version="1.0" encoding="UTF-8"?>')
                                     .encode("latin-1"), ("not valid UTF-8 text",)),
    "NUL byte": (QUAD_URDF.encode().replace(b"<link", b"<li\0nk", 1), ("not well-formed XML",)),
    "truncated": (QUAD_URDF.encode()[: len(QUAD_URDF) // 2], ("not well-formed XML",)),
    "empty": (b"", ("not well-formed XML",)),
    "entity expansion (billion laughs)": (ENTITY_BOMB.encode(), ("<!ENTITY",)),
    "unknown encoding": (QUAD_URDF.replace('version="1.0"', 'version="1.0" encoding="klingon"', 1).encode(),
                         ("unknown encoding 'klingon'",)),
    "a codec that is not a text encoding": (QUAD_URDF.replace('version="1.0"', 'version="1.0" encoding="rot13"', 1)
                                            .encode(), ("unknown encoding 'rot13'",)),
    "a lone surrogate": (QUAD_URDF.replace('version="1.0"', 'version="1.0" encoding="unicode_escape"', 1)
                         .replace("Quadrotor scene", "\\ud800", 1).encode(), ("lone surrogate",)),
    "elements nested 20000 deep": (('<?xml version="1.0"?>\n<robot name="r">' + "<a>" * 20000 + "</a>" * 20000
                                    + "</robot>").encode(), ("nested at most 64 levels deep",)),
    "UTF-16 without a mark, with a NUL": (QUAD_URDF.replace('version="1.0"', 'version="1.0" encoding="UTF-16LE"', 1)
                                          .replace("<link", "<li\0nk", 1).encode("utf-16-le"),
                                          ("not well-formed XML",)),
}


@pytest.mark.parametrize("case", sorted(URDF_CASES))
def test_a_bad_urdf_is_refused_naming_it(capfd, tmp_path, case):
    data, words = URDF_CASES[case]
    scene, urdf = quad_scene(tmp_path, data)
    line = refused(capfd, urdf, "run", str(scene), "--quiet", words=("[model].urdf",) + words)
    assert str(scene) in line  # and the scene that names it


def test_an_oversized_urdf_is_refused_before_it_is_read(capfd, tmp_path, monkeypatch):
    from geoddp.models import urdf as urdf_checks

    monkeypatch.setattr(urdf_checks, "MAX_XML_BYTES", 4096)  # the real limit is 64 MiB: not written in a test
    scene, urdf = quad_scene(tmp_path, (QUAD_URDF + "<!--" + "x" * 8192 + "-->").encode())
    refused(capfd, urdf, "run", str(scene), "--quiet", words=("expected a URDF file of at most",))


@pytest.mark.parametrize("case", ["garbage", "truncated", "entity expansion"])
def test_a_bad_satellite_urdf_is_refused_naming_it(capfd, tmp_path, case):
    data = {"garbage": bytes(range(255, -1, -1)) * 4, "truncated": SAT_URDF.encode()[:120],
            "entity expansion": ENTITY_BOMB.encode()}[case]
    (tmp_path / "sat.urdf").write_bytes(data)
    scene = tmp_path / "scene.toml"
    scene.write_text(SAT_SCENE.replace("[model]\n", '[model]\nurdf = "sat.urdf"\n', 1), encoding="utf-8")
    refused(capfd, tmp_path / "sat.urdf", "run", str(scene), "--quiet", words=("[model].urdf",))


@pytest.mark.parametrize("case", ["declared ISO-8859-1", "UTF-8 byte-order mark", "UTF-16 with its mark",
                                  "UTF-16 without a mark, declared"])
def test_urdf_encodings_xml_allows_are_decoded_and_solve_the_same(capfd, tmp_path, quad_cost, case):
    data = {"declared ISO-8859-1": DECLARED.encode("latin-1"),
            "UTF-8 byte-order mark": codecs.BOM_UTF8 + QUAD_URDF.encode("utf-8"),
            "UTF-16 with its mark": QUAD_URDF.encode("utf-16"),
            "UTF-16 without a mark, declared": DECLARED.replace("ISO-8859-1", "UTF-16BE").encode("utf-16-be")}[case]
    scene, _ = quad_scene(tmp_path, data)
    assert solved_cost(capfd, scene) == quad_cost


@pytest.mark.parametrize("uri", ["package://../../etc/passwd", "package://", "", "file:///tmp",
                                 "a/" * 3000 + "x.stl"])
def test_weird_mesh_paths_are_missing_meshes_and_the_solve_runs(capfd, tmp_path, quad_cost, uri):
    # the solve does not need meshes: a mesh path that names nothing (even one too long for the
    # file system) is a missing mesh, which the replay names; the result is the same
    text = QUAD_URDF.replace("<box", f'<mesh filename="{uri}"/><box', 1)
    scene, _ = quad_scene(tmp_path, text.encode())
    assert solved_cost(capfd, scene) == quad_cost


# ------------------------------------------------------------------ SRDF


def srdf(body: str) -> bytes:
    return f'<?xml version="1.0"?>\n<robot name="quadrotor">{body}</robot>\n'.encode()


HOVER = '<group_state name="up" group="all"><joint name="root_joint" value="0 0 1 0 0 0 1"/></group_state>'
SRDF_CASES = {
    "binary garbage": (bytes(range(256)) * 4, ("not valid UTF-8 text",)),
    "Latin-1 bytes, undeclared": (srdf(HOVER.replace('"up"', '"\u00e9t\u00e9"')).decode().encode("latin-1"),
                                  ("not valid UTF-8 text",)),
    "truncated": (srdf(HOVER)[:60], ("not well-formed XML",)),
    "empty": (b"", ("not well-formed XML",)),
    "entity expansion": (ENTITY_BOMB.encode(), ("<!ENTITY",)),
    "not an SRDF": (b'<?xml version="1.0"?><model/>', ("a <robot> root element",)),
    "elements nested 100000 deep (Pinocchio's reader crashed)": (srdf("<a>" * 100000 + "</a>" * 100000),
                                                                 ("nested at most 64 levels deep",)),
    "a group state without a name": (srdf('<group_state group="all"/>'), ("without a name",)),
    "a joint value of NaN": (srdf(HOVER.replace("0 0 1 0 0 0 1", "nan nan nan nan nan nan nan")),
                             ("group_state 'up', joint 'root_joint'", "expected 7 finite numbers")),
    "a joint value of the wrong length": (srdf(HOVER.replace("0 0 1 0 0 0 1", "0 0 1")), ("expected 7 finite",)),
    "a joint value that is not numbers": (srdf(HOVER.replace("0 0 1 0 0 0 1", "0 0 1 0 0 0 one")),
                                          ("expected 7 finite",)),
}


@pytest.mark.parametrize("case", sorted(SRDF_CASES))
def test_a_bad_srdf_is_refused_naming_it(capfd, tmp_path, case):
    data, words = SRDF_CASES[case]
    scene, _ = quad_scene(tmp_path, QUAD_URDF.encode(), '\nsrdf = "m.srdf"', initial='q = "up"')
    (tmp_path / "m.srdf").write_bytes(data)
    refused(capfd, tmp_path / "m.srdf", "run", str(scene), "--quiet", words=("[model].srdf",) + words)


def test_a_good_srdf_posture_is_read_whatever_the_file_is_called(capfd, tmp_path, quad_cost):
    # Pinocchio's file loader refused any name not ending in .srdf (an internal error here before);
    # the posture read is the translation the scene file gives, so the solve is the same
    scene, _ = quad_scene(tmp_path, QUAD_URDF.encode(), '\nsrdf = "postures.xml"', initial='q = "up"')
    (tmp_path / "postures.xml").write_bytes(srdf(HOVER))
    assert solved_cost(capfd, scene) == quad_cost


# ------------------------------------------------------------------ scene files (TOML)

SCENE_CASES = {
    "binary garbage": (bytes(range(256)) * 4, ("expected UTF-8 text, got invalid bytes at offset",)),
    "Latin-1 bytes": (SAT_SCENE.replace("name =", "# \u00e9t\u00e9\nname =", 1).encode("latin-1"),
                      ("expected UTF-8 text",)),
    "UTF-16": (SAT_SCENE.encode("utf-16"), ("UTF-16 or UTF-32 byte-order mark",)),
    "NUL byte": (SAT_SCENE.replace("name =", "# a\0b\nname =", 1).encode(), ("malformed TOML at line",)),
    "truncated": (SAT_SCENE.encode()[: SAT_SCENE.index("[horizon]") + 4], ("malformed TOML",)),
    "arrays nested 100000 deep": (("x = " + "[" * 100000 + "]" * 100000 + "\n" + SAT_SCENE).encode(),
                                  ("nested too deep",)),
    "inline tables nested 5000 deep": (("x = " + "{a=" * 5000 + "1" + "}" * 5000 + "\n" + SAT_SCENE).encode(),
                                       ("nested too deep",)),
    "arrays nested 100 deep": (("x = " + "[" * 100 + "]" * 100 + "\n" + SAT_SCENE).encode(),
                               ("nested at most 32 levels deep",)),
    "dotted keys 5000 deep": (("a" + ".a" * 5000 + " = 1\n" + SAT_SCENE).encode(), ("nested at most 32 levels",)),
    "a decimal integer of 5000 digits": (SAT_SCENE.replace("max_iter = 200", "max_iter = " + "9" * 5000, 1).encode(),
                                         ("TOML integers are 64-bit",)),
    "a hexadecimal integer of 20000 bits": (SAT_SCENE.replace("max_iter = 200", "max_iter = 0x" + "f" * 5000, 1)
                                            .encode(), ("expected a 64-bit integer", "solver.max_iter")),
}


@pytest.mark.parametrize("case", sorted(SCENE_CASES))
def test_a_bad_scene_file_is_refused_naming_it(capfd, tmp_path, case):
    data, words = SCENE_CASES[case]
    assert data != SAT_SCENE.encode()
    scene = tmp_path / "scene.toml"
    scene.write_bytes(data)
    refused(capfd, scene, "run", str(scene), "--quiet", words=("scene file",) + words)


def test_a_scene_file_with_a_utf8_byte_order_mark_is_read(capfd, tmp_path):
    plain, marked = tmp_path / "plain.toml", tmp_path / "marked.toml"
    plain.write_bytes(SAT_SCENE.encode())
    marked.write_bytes(codecs.BOM_UTF8 + SAT_SCENE.encode())
    assert solved_cost(capfd, marked) == solved_cost(capfd, plain)


# ------------------------------------------------------------------ sweep files


SWEEP_HEAD = '[sweep]\nscene = "satellite_paper"\n'
SWEEP_CASES = {
    "binary garbage": (bytes(range(256)) * 4, "sw.toml", ("sweep file", "expected UTF-8 text")),
    "Latin-1 bytes": ((SWEEP_HEAD + "# \u00e9t\u00e9\n").encode("latin-1"), "sw.toml", ("sweep file",)),
    "arrays nested 100000 deep": ((SWEEP_HEAD + '[grid]\n"cost.control" = ' + "[" * 100000 + "]" * 100000).encode(),
                                  "sw.toml", ("nested too deep",)),
    "a grid key 3000 parts deep": ((SWEEP_HEAD + '[grid]\n"' + "a." * 3000 + 'b" = [1]\n').encode(), "sw.toml",
                                   ("[grid]", "expected a key path of at most 32 parts")),
    "a seed of 40 digits": ((SWEEP_HEAD + "seed = " + "9" * 40 + "\n").encode(), "sw.toml", ("sweep.seed",)),
    "its scene file in Latin-1": (b'[sweep]\nscene = "s.toml"\n', "s.toml", ("[sweep].scene", "expected UTF-8 text")),
    "its scene file nested too deep": (b'[sweep]\nscene = "s.toml"\n', "s.toml", ("[sweep].scene", "nested too deep")),
    "its scene's URDF in Latin-1": (b'[sweep]\nscene = "s.toml"\n', "m.urdf", ("[model].urdf", "not valid UTF-8")),
}


@pytest.mark.parametrize("case", sorted(SWEEP_CASES))
def test_a_bad_sweep_file_is_refused_naming_it(capfd, tmp_path, case):
    data, named, words = SWEEP_CASES[case]
    (tmp_path / "sw.toml").write_bytes(data)
    if case == "its scene file in Latin-1":
        (tmp_path / "s.toml").write_bytes(SAT_SCENE.replace("name =", "# \u00e9\nname =", 1).encode("latin-1"))
    elif case == "its scene file nested too deep":
        (tmp_path / "s.toml").write_bytes(("x = " + "[" * 100000 + "]" * 100000 + "\n" + SAT_SCENE).encode())
    elif case == "its scene's URDF in Latin-1":
        quad_scene(tmp_path, LATIN1.encode("latin-1"))
        (tmp_path / "scene.toml").rename(tmp_path / "s.toml")
    refused(capfd, tmp_path / named, "sweep", str(tmp_path / "sw.toml"), "--out", str(tmp_path / "out"), "--serial",
            "--quiet", words=words)
    assert not (tmp_path / "out" / "parts").exists()  # refused before any case ran


def test_a_huge_value_in_a_message_is_cut_to_one_readable_line(capfd, tmp_path):
    # a message quoting a huge value keeps the parameter (its start) and the file (its end)
    scene = tmp_path / "scene.toml"
    huge = SAT_SCENE.replace('expansion = "switch"', 'expansion = "' + "x" * 100000 + '"', 1)
    scene.write_text(huge, encoding="utf-8")
    line = refused(capfd, scene, "run", str(scene), "--quiet", words=("[solver].expansion", "characters ..."))
    assert len(line) < 2200


def test_a_broken_part_file_of_a_sweep_is_refused_naming_it(capfd, tmp_path):
    # parts are written atomically: only another program leaves a broken one; resume and the
    # summary name it (they raised pyarrow's ArrowInvalid, exit 3, before)
    from geoddp.sweep.table import part_files

    sweep = tmp_path / "sw.toml"
    sweep.write_text(SWEEP_HEAD + 'seed = 1\nsamples = 2\n[scene]\nhorizon.tf = 0.3\nhorizon.dt = 0.05\n[[random]]\n'
                     'key = "target.quaternion"\ndistribution = "haar"\n', encoding="utf-8")
    out = tmp_path / "out"
    rc, stdout, err = run_cli(capfd, "sweep", str(sweep), "--out", str(out), "--serial", "--quiet", "--limit", "1")
    assert rc == 1 and err == [] and "1 solved now" in stdout
    part = part_files(out)[0]
    part.write_bytes(b"PAR1 not really")
    words = ("--out", "not a sweep's Parquet file", "move it out of the folder")
    refused(capfd, part, "sweep", str(sweep), "--out", str(out), "--serial", "--quiet", "--resume", words=words)
    refused(capfd, part, "sweep", "--summary", str(out), words=words)


def test_a_spin_that_overflows_the_rollout_is_refused_not_returned_with_nan_states(capfd, tmp_path):
    # Found by benchmarks/fuzz.py: the satellite's rollout kernel stops at the first non-finite
    # state and left the later steps unwritten; a cost read them as finite (J = 15000) and the
    # result JSON held NaN states (written as null). Now the initial guess is refused.
    text = scene_path("tumbling_5rads").read_text(encoding="utf-8")
    assert "angular_velocity = [2.4, -3.0, 3.2]" in text
    scene = tmp_path / "spin.toml"
    scene.write_text(text.replace("angular_velocity = [2.4, -3.0, 3.2]", "angular_velocity = [2.4, -3.0, 3.2e12]"),
                     encoding="utf-8")
    out = tmp_path / "out.json"
    rc, stdout, err = run_cli(capfd, "run", str(scene), "--quiet", "--json", str(out))
    assert rc == 2 and len(err) == 1 and not out.exists(), (rc, err)
    assert err[0].startswith("geoddp: error: initial_controls: the initial guess gives a non-finite cost J = nan")


def test_the_satellite_rollout_is_nan_throughout_once_it_overflows():
    import numpy as np

    from geoddp.models.satellite import Satellite

    sat = Satellite(inertia=np.diag([10.0, 11.1, 13.0]), actuation=np.eye(3), dt=0.01)
    R, Om = sat.rollout(np.eye(3), np.array([2.4, -3.0, 3.2e12]), np.zeros((100, 3)))  # off a principal axis
    assert np.isnan(R).all() and np.isnan(Om).all()
    R, Om = sat.rollout(np.eye(3), np.array([0.1, 0.2, 0.3]), np.zeros((100, 3)))
    assert np.isfinite(R).all() and np.isfinite(Om).all()
