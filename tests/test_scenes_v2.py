"""Issue-15 scene families: registration, deterministic exposure, offline photographs, meshes, the
reference-noise check, the v2 preset's plan, and (on the tiny preset) rendering and convergence."""

from __future__ import annotations

import math
import socket
from pathlib import Path

import numpy as np
import pytest

mi = pytest.importorskip("mitsuba")

from data_gen.convergence import (  # noqa: E402
    MAX_REFERENCE_NOISE,
    dataset_verdicts,
    reference_noise,
    reference_noise_ratio,
)
from data_gen.plan import derive_seed, plan_dataset  # noqa: E402
from data_gen.scenes import _exposure, _photos, get_scene, list_scenes  # noqa: E402  # noqa: E402
from data_gen.scenes._exposure import emitter_strengths, exposure, scale_emitters  # noqa: E402
from nriqa.io.exr import read_exr  # noqa: E402
from nriqa.io.manifest import read_manifest  # noqa: E402

NEW = (
    "photo",
    "dim_interior",
    "glass_floor",
    "dof",
    "fine_geometry",
    "exterior",
    "lamps",
    "clutter",
    "textured_light",
    "surfaces",
    "strands",
    "foliage",
    "shafts",
    "pebbles",
    "turned_light",
    "trinkets",
    "blinds",
)
# On the tiny preset (references at 16x the ladder's top) one new ladder's top rung outruns its
# reference: the lamps are small, and multi-jittered sampling finds them about 6x as efficiently as the
# independent reference does, so 16x the samples are not 4x the precision. v2's rung limit stops it.
TINY_REFERENCE_TOO_NOISY = {("lamps", "path_multijitter")}
PRESETS = Path(__file__).resolve().parents[1] / "data_gen" / "configs" / "preset"


@pytest.fixture(scope="module", autouse=True)
def _variant():
    """Scenes are built with Mitsuba's transforms and bitmaps: any variant will do."""
    if mi.variant() is None:
        mi.set_variant("scalar_rgb")


def test_seventeen_families_or_more_with_the_issue_15_ones():
    scenes = list_scenes()
    assert len(scenes) >= 17 and set(NEW) <= set(scenes)
    for name in NEW:
        spec = get_scene(name)
        assert spec.summary and "2^U(-3,3)" in spec.summary


def test_particle_tracing_is_declared_only_where_the_camera_sees_no_specular_chain():
    """Glass and the thin lens defeat particle tracing (the tiny-preset check confirms the rest)."""
    for name in ("glass_floor", "dof", "exterior"):
        assert "ptracer_independent" not in get_scene(name).algorithms


# --- exposure --------------------------------------------------------------------------------------


def _unit_exposure(rng, stops=3.0):
    """Draws what :func:`exposure` draws (so the rest of the build is unchanged) but returns 1."""
    rng.uniform(-stops, stops)
    return 1.0


@pytest.mark.parametrize("name", NEW)
def test_every_emitter_scaled_by_the_seeds_exposure(name, monkeypatch):
    spec = get_scene(name)
    module = __import__(spec.build.__module__, fromlist=["build"])
    gains = []
    for v in range(16):
        seed = derive_seed(0, name, v)
        built = emitter_strengths(spec.build(np.random.default_rng(seed)))
        again = emitter_strengths(spec.build(np.random.default_rng(seed)))
        assert built == again and built, "same seed, same emitters"
        gain = exposure(np.random.default_rng(seed))
        with monkeypatch.context() as m:
            m.setattr(module, "exposure", _unit_exposure)
            base = emitter_strengths(spec.build(np.random.default_rng(seed)))
        assert base.keys() == built.keys()
        for key in built:
            assert built[key] == pytest.approx(gain * base[key], rel=1e-6), key
        gains.append(gain)
    assert all(2**-3 <= g <= 2**3 for g in gains)
    assert math.log2(max(gains) / min(gains)) > 3, "16 variants span more than 3 stops"


def test_scale_emitters_scales_every_kind_and_refuses_unknown_ones():
    scene = {
        "type": "scene",
        "lamp": {"type": "rectangle", "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [1, 2, 3]}}},
        "sky": {"type": "envmap", "filename": "x.exr"},
        "sun": {"type": "directional", "irradiance": 4.0},
        "spot": {"type": "spot", "intensity": {"type": "rgb", "value": [2, 2, 2]}},
        "wall": {"type": "rectangle"},
    }
    out = scale_emitters(scene, 0.5)
    assert out["lamp"]["emitter"]["radiance"]["value"] == [0.5, 1.0, 1.5]
    assert out["sky"]["scale"] == 0.5 and out["sun"]["irradiance"] == 2.0
    assert out["spot"]["intensity"]["value"] == [1, 1, 1]
    assert out["wall"] == scene["wall"] and scene["sun"]["irradiance"] == 4.0, "the input is not modified"
    assert emitter_strengths(out) == {"lamp": 1.0, "sky": 0.5, "sun": 2.0, "spot": 1.0}
    with pytest.raises(ValueError, match="cannot scale emitter of type 'sunsky'"):
        scale_emitters({"p": {"type": "sunsky"}}, 2.0)
    with pytest.raises(ValueError, match="without 'intensity'"):
        scale_emitters({"p": {"type": "point"}}, 2.0)
    with pytest.raises(ValueError, match="stops"):
        exposure(np.random.default_rng(0), -1)


def test_scale_emitters_scales_projectors_and_textured_radiance():
    """A projector's ``scale`` (1 when unset) and an area light whose radiance is a bitmap of an array."""
    pattern = np.arange(12, dtype=np.float32).reshape(2, 2, 3)
    scene = {
        "projector": {"type": "projector", "irradiance": {"type": "rgb", "value": [1, 1, 1]}},
        "screen": {
            "type": "rectangle",
            "emitter": {"type": "area", "radiance": {"type": "bitmap", "bitmap": mi.Bitmap(pattern)}},
        },
    }
    out = scale_emitters(scene, 0.25)
    assert out["projector"]["scale"] == 0.25 and out["projector"]["irradiance"] == scene["projector"]["irradiance"]
    np.testing.assert_array_equal(np.asarray(out["screen"]["emitter"]["radiance"]["bitmap"]), pattern * 0.25)
    np.testing.assert_array_equal(np.asarray(scene["screen"]["emitter"]["radiance"]["bitmap"]), pattern), "input kept"
    assert emitter_strengths(out) == {"projector": 0.25, "screen": pytest.approx(5.5 * 0.25)}
    assert mi.load_dict({"type": "scene", **out}) is not None


def test_the_new_surfaces_load_in_mitsuba_and_unknown_ones_are_refused():
    from data_gen.scenes.surfaces import SURFACES, surface

    rng = np.random.default_rng(0)
    for kind in SURFACES:
        assert mi.load_dict(surface(rng, kind)) is not None, kind
    with pytest.raises(ValueError, match="unknown surface 'velvet'"):
        surface(rng, "velvet")


def test_scale_emitters_knows_every_emitter_the_new_families_use():
    assert set(_exposure.STRENGTH) >= {"area", "constant", "envmap", "spot"}
    for name in NEW:
        scene = get_scene(name).build(np.random.default_rng(1))
        assert emitter_strengths(scene), name


# --- photographs -------------------------------------------------------------------------------------


def test_photographs_load_from_the_wheel_with_the_network_off(monkeypatch):
    def refuse(*args, **kwargs):
        raise OSError("network is off in this test")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    _photos.load_photo.cache_clear()
    for name in _photos.PHOTOS:
        path = _photos.photo_path(name)
        assert path.is_file() and "skimage" in path.parts, path
        img = _photos.load_photo(name)
        assert img.dtype == np.float32 and img.ndim == 3 and img.shape[2] == 3
        assert max(img.shape[:2]) <= _photos.MAX_SIZE and 0 <= img.min() and img.max() <= 1 and img.std() > 0.01, name
    with pytest.raises(KeyError, match="unknown photo"):
        _photos.load_photo("lena")


def test_srgb_decoding_matches_the_standard_curve():
    x = np.array([0.0, 0.04045, 0.5, 1.0])
    np.testing.assert_allclose(_photos.srgb_to_linear(x), [0.0, 0.04045 / 12.92, 0.21404, 1.0], rtol=1e-4)


def test_photo_texture_is_a_reflectance_below_one():
    tex = _photos.photo_texture(np.random.default_rng(3), "brick", tiles=(2, 1))
    data = np.array(tex["bitmap"])
    assert tex["raw"] and 0 < data.max() <= _photos.MAX_REFLECTANCE + 1e-6


# --- meshes ---------------------------------------------------------------------------------------------


def test_rods_and_heightfield_meshes():
    from data_gen.scenes._meshes import heightfield_mesh, rods_mesh

    bsdf = {"type": "diffuse"}
    rods = rods_mesh("r", [[0, 0, 0], [1, 0, 0]], [[0, 1, 0], [1, 0, 2]], 0.01, bsdf, sides=6)
    assert (rods.vertex_count(), rods.face_count()) == (2 * 12, 2 * (12 + 8))
    field = heightfield_mesh("h", np.zeros((5, 5)), 2.0, bsdf)
    assert (field.vertex_count(), field.face_count()) == (25, 32)
    assert field.surface_area() == pytest.approx(4.0, rel=1e-5)
    with pytest.raises(ValueError, match="distinct end points"):
        rods_mesh("r", [[0, 0, 0]], [[0, 0, 0]], 0.01, bsdf)


def test_prism_faces_face_outward_either_way_round():
    from data_gen.scenes._meshes import prism_faces

    sides = 7
    ang = 2 * np.pi * np.arange(sides) / sides
    ccw = np.stack([np.cos(ang), np.sin(ang), np.zeros(sides)], 1)  # counter-clockwise about +z
    for ring, clockwise in ((ccw, False), (ccw[:, [1, 0, 2]], True)):  # swapping x and y runs it clockwise
        pos = np.concatenate([ring, ring + [0.0, 0.0, 3.0]])  # moved along +z
        faces = prism_faces(sides, 1, clockwise)
        assert faces.shape == (4 * (sides - 1), 3)
        a, b, c = (pos[faces[:, i]] for i in range(3))
        normal = np.cross(b - a, c - a)
        outward = (a + b + c) / 3 - [0.0, 0.0, 1.5]  # from the prism's centre to each face
        assert (np.einsum("ij,ij->i", normal, outward) > 0).all()
    assert prism_faces(3, 2).max() == 2 * 2 * 3 - 1  # prism i's vertices follow prism i - 1's


def test_strand_fibres_stand_taper_and_become_meshes():
    from data_gen.scenes.strands import CONTROL_POINTS, _tuft, fibres

    pts = fibres(np.random.default_rng(3), 40, 0.5, 0.4, 0.005)
    assert pts.shape == (40, CONTROL_POINTS, 4)
    assert (pts[:, 0, 1] == 0).all() and (pts[:, -1, 1] >= 0.4 * 0.6 - 1e-12).all(), "rooted on the ground, standing"
    assert (np.diff(pts[..., 1], axis=1) > 0).all(), "every segment rises: none is degenerate"
    assert np.allclose(pts[:, -1, 3], 0.001) and np.allclose(pts[:, 0, 3], 0.005), "thin from root to tip"
    assert (np.hypot(pts[:, 0, 0], pts[:, 0, 2]) <= 0.5).all()
    meshes = _tuft(np.random.default_rng(4), "t", [0.0, 0.0], 30, 0.4, 0.005)
    assert len(meshes) == CONTROL_POINTS - 1
    assert all(m.face_count() == 30 * (2 * 4 + 2 * 2) for m in meshes), "30 four-sided prisms a segment"


def test_blinds_slats_screen_and_cables_span_the_window_and_the_room():
    from data_gen.scenes.blinds import D, W, build, cables, screen, slats

    pos, faces = slats(2.0, -1.0, 1.0, 0.5, 2.0, pitch=0.05, depth=0.04, tilt=30)
    count = len(np.arange(0.525, 2.0, 0.05))
    assert pos.shape == (4 * count, 3) and faces.shape == (2 * count, 3) and faces.max() == 4 * count - 1
    assert set(np.round(pos[:, 2], 9)) == {-1.0, 1.0}, "every slat spans the window's width"
    assert (pos[:, 0] < 2.0).all() and (pos[:, 1] > 0.5 - 0.04).all() and (pos[:, 1] < 2.0 + 0.04).all()
    rise = pos[1::4, 1] - pos[0::4, 1]
    assert np.allclose(rise, 0.04 * np.sin(np.radians(30))), "turned by the tilt about its long axis"
    starts, ends = screen(2.02, -1.0, 1.0, 0.5, 2.0, 0.02)
    assert starts.shape == ends.shape and len(starts) == 101 + 76 and (np.abs(starts[:, 0] - 2.02) < 0.01).all()
    a, b = cables(np.random.default_rng(5), 3)
    assert a.shape == b.shape == (36, 3) and np.allclose(a[1:12], b[:11]), "a cable's segments join end to end"
    assert np.isclose(a[::12, 0], -W).all() and np.isclose(b[11::12, 0], W).all(), "strung from wall to wall"
    mid = a[6::12, 1]
    assert (mid < np.maximum(a[::12, 1], b[11::12, 1])).all(), "each sags between its ends"
    assert (np.abs(a[:, 2]) <= D).all()
    scene = build(np.random.default_rng(derive_seed(1, "blinds", 70)))
    assert scene["sun"]["direction"][0] < 0 and scene["sun"]["direction"][1] < 0, "the sun shines in, downward"
    assert scene["slats"].face_count() > 20


def test_leaf_outline_is_pointed_and_notched():
    from data_gen.scenes._meshes import leaf_outline

    smooth, toothed = leaf_outline(1.0, 0.3, 0), leaf_outline(1.0, 0.3, 4)
    assert smooth.shape == toothed.shape == (14, 2)
    assert tuple(smooth[0]) == (0.0, 0.0) and tuple(smooth[7]) == (0.0, 1.0), "base and tip on the midrib"
    assert np.allclose(smooth[1:7, 0], -smooth[8:][::-1, 0]), "the two halves mirror each other"
    assert 0 < np.abs(smooth[:, 0]).max() <= 0.3
    assert (np.abs(toothed[:, 0]) <= np.abs(smooth[:, 0]) + 1e-12).all() and not np.allclose(toothed, smooth)


def test_leaves_become_one_folded_coloured_mesh():
    from data_gen.scenes._meshes import VERTEX_COLOR, leaf_outline, leaves_mesh

    outline = leaf_outline(1.0, 0.3, 0)
    bsdf = {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": VERTEX_COLOR}}
    bases, normals, ups = [[0, 0, 0], [1, 0, 0]], [[0, 1, 0], [0, 0, 1]], [[0, 0, 1], [0, 1, 0]]
    flat = leaves_mesh(
        "l", bases, normals, ups, outline, [1.0, 2.0], bsdf, fold=0.0, colors=[[0.1, 0.3, 0], [0.5, 0.2, 0]]
    )
    assert (flat.vertex_count(), flat.face_count()) == (2 * 15, 2 * 14), "a fan of 14 triangles a leaf"
    x, y = outline[:, 0], outline[:, 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    assert flat.surface_area() == pytest.approx(area * (1 + 4), rel=1e-5), "each leaf its outline's area, scaled"
    pos = np.array(mi.traverse(flat)["vertex_positions"]).reshape(-1, 3)
    assert np.allclose(pos[:15, 1], 0) and np.allclose(pos[15:, 2], 0), "flat: in the plane its normal gives"
    assert pos[:15, 2].max() == pytest.approx(1.0) and pos[15:, 1].max() == pytest.approx(2.0), "grows along its up"
    folded = leaves_mesh("f", bases[:1], normals[:1], ups[:1], outline, 1.0, bsdf, fold=0.4)
    assert (
        folded.surface_area() > area
        and np.array(mi.traverse(folded)["vertex_positions"]).reshape(-1, 3)[:, 1].max() > 0
    )
    assert flat.has_attribute("vertex_color") and not folded.has_attribute("vertex_color")
    with pytest.raises(ValueError, match="must not lie along its normal"):
        leaves_mesh("b", bases[:1], normals[:1], normals[:1], outline, 1.0, bsdf)
    with pytest.raises(ValueError, match="of one N"):
        leaves_mesh("b", bases, normals[:1], ups, outline, 1.0, bsdf)


def test_foliage_colours_its_leaves_one_by_one_and_looks_up_a_third_of_the_time():
    from data_gen.scenes.foliage import GREEN, leaf_colors

    colours = leaf_colors(np.random.default_rng(0), 500, GREEN)
    assert colours.shape == (500, 3) and (colours > 0).all() and (colours <= 0.9).all()
    assert len(np.unique(colours[:, 1])) == 500 and (colours[:, 1] > colours[:, 2]).mean() > 0.9, "green, each its own"
    spec = get_scene("foliage")
    ups = []
    for v in range(24):
        scene = spec.build(np.random.default_rng(derive_seed(0, "foliage", v)))
        to_world = np.array(scene["sensor"]["to_world"].matrix)
        origin, forward = to_world[:3, 3], to_world[:3, 2]
        ups.append(forward[1] > 0)
        assert {"canopy", "sun", "sky", "ground", "bush0_0"} <= set(scene) and origin[1] > 0
    assert 0.15 < np.mean(ups) < 0.55, "about a third of the views look up through the canopy"


def test_pebbles_lie_on_the_ground_each_stone_its_own_colour():
    from data_gen.scenes.pebbles import ICOSA_FACES, ICOSA_VERTICES, stones_mesh

    assert np.allclose(np.linalg.norm(ICOSA_VERTICES, axis=1), 1)
    edges = np.sort(np.concatenate([ICOSA_FACES[:, [0, 1]], ICOSA_FACES[:, [1, 2]], ICOSA_FACES[:, [2, 0]]]), axis=1)
    assert len(np.unique(edges, axis=0)) == 30, "a closed icosahedron: 30 edges, each shared by two faces"
    mesh = stones_mesh("s", np.random.default_rng(0), 200, 1.0, np.full(200, 0.05), {"type": "diffuse"})
    params = mi.traverse(mesh)
    pos = np.array(params["vertex_positions"]).reshape(-1, 3)
    assert len(pos) == 200 * 12 and mesh.face_count() == 200 * 20
    assert pos[:, 1].min() < 0 < pos[:, 1].max() < 0.05, "sunk a little into the ground, flatter than wide"
    assert np.abs(pos[:, [0, 2]]).max() < 1.05
    colours = np.array(mesh.attribute_buffer("vertex_color")).reshape(-1, 3)
    assert len(np.unique(colours[::12], axis=0)) > 190 and (colours[::12] == colours[11::12]).all(), (
        "one colour a stone"
    )
    spec = get_scene("pebbles")
    down, suns = [], []
    for v in range(24):
        scene = spec.build(np.random.default_rng(derive_seed(0, "pebbles", v)))
        forward = np.array(scene["sensor"]["to_world"].matrix)[:3, 2]
        down.append(forward[1] < -0.9)
        suns.append("sun" in scene)
        assert {"stones", "sky", "ground"} <= set(scene) and forward[1] < 0
    assert 0.1 < np.mean(down) < 0.5 and 0.5 < np.mean(suns) < 0.95, "some views straight down, some overcast"


def test_trinkets_are_smooth_beads_flat_coins_and_pins_on_the_surface():
    from data_gen.scenes.trinkets import beads_mesh, coins_mesh, icosphere

    unit, faces = icosphere()
    assert unit.shape == (42, 3) and faces.shape == (80, 3) and np.allclose(np.linalg.norm(unit, axis=1), 1)
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    assert len(np.unique(edges, axis=0)) == 120, "a closed sphere: every edge shared by two faces"
    normals = np.cross(unit[faces[:, 1]] - unit[faces[:, 0]], unit[faces[:, 2]] - unit[faces[:, 0]])
    assert (np.einsum("ij,ij->i", normals, unit[faces].mean(1)) > 0).all(), "wound outwards"
    rng = np.random.default_rng(0)
    radii = np.full(100, 0.02)
    centres = np.stack([rng.uniform(-1, 1, 100), radii, rng.uniform(-1, 1, 100)], 1)
    beads = mi.traverse(beads_mesh("b", rng, centres, radii, {"type": "diffuse"}))
    pos = np.array(beads["vertex_positions"]).reshape(-1, 3)
    assert len(pos) == 100 * 42 and np.allclose(pos[:, 1].min(), 0, atol=1e-6), "each bead rests on the surface"
    assert len(np.array(beads["vertex_normals"])) == len(pos) * 3, "smooth shaded: sharp highlights"
    coins = coins_mesh(
        "c", rng, np.stack([centres[:, 0], np.zeros(100), centres[:, 2]], 1), radii * 2, {"type": "diffuse"}
    )
    cpos = np.array(mi.traverse(coins)["vertex_positions"]).reshape(-1, 3)
    assert coins.face_count() == 100 * (20 + 16) and np.abs(cpos[:, 1]).max() < 0.02, "flat discs, nearly level"
    spec = get_scene("trinkets")
    down, lamps = [], []
    for v in range(24):
        scene = spec.build(np.random.default_rng(derive_seed(0, "trinkets", v)))
        forward = np.array(scene["sensor"]["to_world"].matrix)[:3, 2]
        down.append(forward[1] < -0.9)
        lamps.append("lamp0" in scene)
        assert {"beads", "coins", "ground"} <= set(scene) and forward[1] < 0
        assert ("lamp0" in scene) != ("sun" in scene), "small lamps or the sun, not both"
    assert 0.15 < np.mean(down) < 0.6 and 0.35 < np.mean(lamps) < 0.85, "some views straight down, some sunlit"


def test_shafts_camera_stands_in_the_haze_and_the_sun_comes_in_through_the_window():
    from data_gen.scenes.shafts import GAP, HAZE, D, H, W

    spec = get_scene("shafts")
    assert spec.medium and spec.reference_algorithm == "volpath_independent"
    for v in range(8):
        scene = spec.build(np.random.default_rng(derive_seed(0, "shafts", v)))
        assert scene["sensor"]["medium"] == HAZE == scene["air"]["interior"] and scene["haze"]["type"] == "homogeneous"
        x, y, z = np.array(scene["sensor"]["to_world"].matrix)[:3, 3]
        assert abs(x) < W - GAP and GAP < y < H - GAP and abs(z) < D - GAP, "the camera is inside the hazy air"
        sun = np.array(scene["sun"]["direction"])
        assert sun[0] < 0 and sun[1] < 0, "the sun shines down into the room through the wall x = +W"
        hole = [scene[k]["to_world"] for k in ("east_below", "east_above", "east_left", "east_right")]
        assert all(np.isclose(np.array(m.matrix)[0, 3], W) for m in hole), "the window is in the east wall"


def test_heldout_preset_renders_families_no_shipped_network_learnt():
    cfg = _preset("heldout")
    assert cfg["scenes"] and set(cfg["scenes"]) <= set(list_scenes())
    assert not set(cfg["scenes"]) & set(_preset("v2")["scenes"]), "the shipped scorers learnt v2's families"
    assert (
        cfg["ladder_top"] == _preset("v2")["ladder_top"]
        and cfg["reference_factor"] == _preset("v2")["reference_factor"]
    )


# --- the reference-noise check ---------------------------------------------------------------------------


def test_reference_noise_ratio_is_the_variance_ratio():
    rng = np.random.default_rng(0)
    truth = np.full((64, 64, 3), 0.3, dtype=np.float32)

    def noisy(sigma):
        return (truth + rng.normal(0, sigma, truth.shape)).astype(np.float32)

    test, twin = noisy(0.02), noisy(0.02)
    ref_pair = (noisy(0.02), noisy(0.02))  # the reference algorithm's top rung at the test image's noise
    assert reference_noise_ratio(test, twin, ref_pair, 1 / 16) == pytest.approx(1 / 16, rel=0.15)
    assert reference_noise_ratio(test, twin, ref_pair, 1.0) > MAX_REFERENCE_NOISE, "as noisy as the test: fails"


# --- presets -----------------------------------------------------------------------------------------------


def _preset(name: str) -> dict:
    from omegaconf import OmegaConf

    return OmegaConf.to_container(OmegaConf.load(PRESETS / f"{name}.yaml"))


def test_tiny_preset_holds_every_family():
    assert sorted(_preset("tiny")["scenes"]) == list_scenes()


def test_v2_preset_plan():
    cfg = _preset("v2")
    assert len(cfg["scenes"]) >= 13 and cfg["variants"] >= 16
    held_out = set(_preset("heldout")["scenes"])
    assert set(list_scenes()) - set(cfg["scenes"]) == {"caustic"} | held_out, "caustic: its reference fails the check"
    assert cfg["ladder_top"] >= 1024 and cfg["ladder_top"] * cfg["reference_factor"] >= 16384
    jobs = plan_dataset(
        cfg["scenes"],
        1,
        resolution=tuple(cfg["resolution"]),
        ladder_top=cfg["ladder_top"],
        reference_factor=cfg["reference_factor"],
    )
    refs = {j.scene: j.tasks[0].spp for j in jobs if j.tasks[0].role == "reference"}
    assert set(refs) == set(cfg["scenes"]) and min(refs.values()) >= 16384
    top = {(j.scene, j.algorithm): max(t.spp for t in j.tasks) for j in jobs if j.tasks[0].role != "reference"}
    to_1024 = {s for (s, a), spp in top.items() if a == get_scene(s).reference_algorithm and spp >= 1024}
    assert to_1024 >= set(NEW) - held_out
    for (scene, alg), spp in top.items():
        limit = get_scene(scene).rung_limits.get(alg)
        assert spp == limit if limit else spp >= cfg["ladder_top"] // 2, (scene, alg)  # square samplers: 4^k


def test_rung_limits_leave_presets_with_smaller_references_as_they_were():
    spps = {j.algorithm: sorted({t.spp for t in j.tasks}) for j in plan_dataset(["shadows"], 1, ladder_top=64)}
    assert spps["path_ldsampler"] == [4, 16, 64] and spps["path_multijitter"] == [4, 16, 64]
    v2 = {j.algorithm: sorted({t.spp for t in j.tasks}) for j in plan_dataset(["shadows"], 1, ladder_top=1024)}
    assert (
        v2["path_ldsampler"] == [4, 16] and v2["path_multijitter"] == [4, 16, 64] and v2["path_independent"][-1] == 1024
    )


def test_plan_goes_variant_by_variant_so_a_stopped_run_holds_whole_variants():
    big = plan_dataset(["cornell", "dof"], 3, ladder_top=16)
    assert [j.variant for j in big] == sorted(j.variant for j in big)
    small = plan_dataset(["cornell", "dof"], 2, ladder_top=16)
    assert big[: len(small)] == small, "the first K variants are the same jobs, first"


def test_rung_limits_end_a_ladder_early_and_are_checked(monkeypatch):
    import dataclasses

    from data_gen import scenes

    spec = dataclasses.replace(get_scene("cornell"), rung_limits={"path_ldsampler": 16, "ptracer_independent": 8})
    monkeypatch.setitem(scenes._REGISTRY, "cornell", spec)
    jobs = plan_dataset(["cornell"], 1, ladder_top=64, reference_factor=scenes.LIMITS_REFERENCE_SPP // 64)
    spps = {j.algorithm: sorted({t.spp for t in j.tasks}) for j in jobs}
    assert spps["path_ldsampler"] == [4, 16] and spps["ptracer_independent"] == [2, 4, 8]
    assert spps["path_multijitter"] == [4, 16, 64] and spps["path_independent"] == [2, 4, 8, 16, 32, 64]
    for bad in ({"path_ldsampler": 2}, {"path_ldsampler": 24}, {"volpath_independent": 16}):
        with pytest.raises(ValueError, match="rung_limits"):
            scenes.register_scene(dataclasses.replace(spec, name="cornell_limited", rung_limits=bad))
    assert "cornell_limited" not in scenes._REGISTRY


# --- rendered: the tiny preset -------------------------------------------------------------------------------


def test_new_families_render_and_converge_on_the_tiny_preset(tiny):
    records, _ = read_manifest(tiny)
    records = [r for r in records if r.scene in NEW]
    verdicts = dataset_verdicts(tiny, records)
    assert {(v["scene"], v["algorithm"]) for v in verdicts} == {(s, a) for s in NEW for a in get_scene(s).algorithms}
    assert all(v["converged"] for v in verdicts), [v for v in verdicts if not v["converged"]]
    noise = reference_noise(tiny, records)
    failing = {(row["scene"], row["algorithm"]) for row in noise if not row["ok"]}
    assert failing <= TINY_REFERENCE_TOO_NOISY, [row for row in noise if not row["ok"]]
    for r in records:
        img = read_exr(tiny / r.path)
        assert np.isfinite(img).all() and img.mean() > 0, r.id


def test_dim_interior_is_mostly_dark_at_two_samples(tiny):
    """Sparse bright samples: at 2 spp more pixels sit far below the reference than in the Cornell box;
    turned_light (moderately dim) lies between the two."""
    records, _ = read_manifest(tiny)

    def dark_fraction(scene):
        rec = next(
            r
            for r in records
            if r.scene == scene and r.algorithm == "path_independent" and r.spp == 2 and r.role == "test"
        )
        lum, ref = read_exr(tiny / rec.path).mean(axis=2), read_exr(tiny / rec.reference).mean(axis=2)
        return float((lum < 0.1 * ref).mean())

    assert dark_fraction("dim_interior") > 0.5 and dark_fraction("dim_interior") > 2 * dark_fraction("cornell")
    # the luminaire turned to a surface: between the two (measured 0.27 against 0.04 and 0.79)
    assert 2 * dark_fraction("cornell") < dark_fraction("turned_light") < dark_fraction("dim_interior") - 0.2


def test_exterior_reference_has_highlights_far_above_one(tiny):
    records, _ = read_manifest(tiny)
    ref = next(r for r in records if r.scene == "exterior" and r.role == "reference")
    assert read_exr(tiny / ref.path).max() > 4


def test_checks_command_passes_on_the_new_families_and_fails_on_a_reference_too_noisy(tiny, tmp_path, capsys):
    """The tiny preset's new families pass both checks; declaring cornell's reference at 2x instead of 16x
    its ladder's top makes the same images fail the reference-noise check."""
    import dataclasses
    import shutil

    from data_gen.convergence import main
    from nriqa.io.manifest import write_manifest

    records, _ = read_manifest(tiny)
    for name, scenes, change in (("new", NEW, {}), ("cornell", ("cornell",), {"spp": 32})):
        root = tmp_path / name
        for scene in scenes:
            shutil.copytree(tiny / scene, root / scene)
        chosen = [r for r in records if r.scene in scenes and (r.scene, r.algorithm) not in TINY_REFERENCE_TOO_NOISY]
        write_manifest(root, [dataclasses.replace(r, **change) if r.role == "reference" else r for r in chosen], {})
    assert main([str(tmp_path / "new")]) == 0
    header = (tmp_path / "new" / "checks" / "reference_noise.csv").read_text().splitlines()[0]
    assert header.startswith("scene,variant,algorithm,spp,reference_spp")
    capsys.readouterr()
    assert main([str(tmp_path / "cornell")]) == 1
    assert "reference too noisy: cornell v000 path_independent 16 spp (ratio 0.5)" in capsys.readouterr().out
    assert main([str(tmp_path / "nowhere")]) == 2

    # --drop-noisy: the failing rungs leave the manifest (files stay), the rest and the reference stay
    before, _ = read_manifest(tmp_path / "cornell")
    capsys.readouterr()
    assert main([str(tmp_path / "cornell"), "--drop-noisy"]) == 0
    assert "images dropped" in capsys.readouterr().out
    after, meta = read_manifest(tmp_path / "cornell")
    assert "cornell/v000/path_independent/16" in meta["dropped_noisy_reference"]
    assert not [r for r in after if r.role != "reference" and r.algorithm == "path_independent" and r.spp == 16]
    assert {r.id for r in after} < {r.id for r in before} and any(r.role == "reference" for r in after)
    assert all((tmp_path / "cornell" / r.path).is_file() for r in before)
    main([str(tmp_path / "cornell")])
    rows = (tmp_path / "cornell" / "checks" / "reference_noise.csv").read_text().splitlines()
    assert not [row for row in rows if row.startswith("cornell,0,path_independent,16,")], (
        "a dropped rung is not checked"
    )


def test_a_reference_its_own_algorithm_disagrees_with_is_suspect_and_its_variant_can_be_dropped(tiny, tmp_path, capsys):
    """cornell's reference made 30 % brighter: its own algorithm's top rung no longer converges to it,
    so every target of the variant is wrong; --drop-suspect takes the variant's test images out."""
    import shutil

    from data_gen.convergence import main
    from nriqa.io.exr import write_exr
    from nriqa.io.manifest import write_manifest

    records, _ = read_manifest(tiny)
    root = tmp_path / "cornell"
    shutil.copytree(tiny / "cornell", root / "cornell")
    chosen = [r for r in records if r.scene == "cornell" and (r.scene, r.algorithm) not in TINY_REFERENCE_TOO_NOISY]
    write_manifest(root, chosen, {})
    assert main([str(root)]) == 0, "as rendered, nothing is suspect"
    assert "suspect" not in capsys.readouterr().out
    ref = next(r for r in chosen if r.role == "reference")
    write_exr(root / ref.path, read_exr(tiny / ref.path) * 1.3)
    assert main([str(root)]) == 1
    assert "reference suspect: cornell v000" in capsys.readouterr().out
    assert len(read_manifest(root)[0]) == len(chosen), "reported, nothing dropped without the flag"
    assert main([str(root), "--drop-suspect"]) == 0, "the variant's failures are handled by dropping it"
    after, meta = read_manifest(root)
    assert meta["dropped_suspect_reference"] == ["cornell/v000"]
    assert [r.role for r in after] == ["reference"] and all((root / r.path).is_file() for r in chosen)


def test_random_materials_and_standing_shapes_load_in_mitsuba():
    from data_gen.scenes._parts import MATERIALS, SHAPES, random_material, standing_shape

    rng = np.random.default_rng(0)
    for kind in MATERIALS:
        bsdf = random_material(rng, (kind,))
        inner = bsdf["bsdf"] if bsdf["type"] == "twosided" else bsdf  # diffuse() is two-sided
        assert inner["type"] == kind and mi.load_dict(bsdf) is not None
    for kind in SHAPES:
        shape = mi.load_dict(standing_shape(kind, 0.5, -0.5, 0.2, {"type": "diffuse"}, turn=30, height=0.6))
        lo, hi = shape.bbox().min, shape.bbox().max
        assert lo.y == pytest.approx(0.0, abs=1e-5), f"{kind} rests on the floor"
        assert hi.y == pytest.approx(0.6 if kind == "cylinder" else 0.4, abs=1e-5), kind
    with pytest.raises(ValueError, match="unknown material"):
        random_material(rng, ("velvet",))
    with pytest.raises(ValueError, match="unknown shape"):
        standing_shape("cone", 0, 0, 1, {"type": "diffuse"})
