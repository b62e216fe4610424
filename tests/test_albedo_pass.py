"""The albedo pass as a second input: rendered beside each reference, loaded with the pairs, cut, textured
and jittered with the image but never displayed, and taken by the Scorer and the evaluation."""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from conftest import CONSTANT, with_albedo
from test_batched_patches import MIX, make_dm

from nriqa.core.display import apply_display
from nriqa.data.albedo import texture
from nriqa.data.images import load_pairs
from nriqa.data.jitter import apply_jitter, sample_jitter
from nriqa.data.patches import TONEMAP, cut_all, item_generator
from nriqa.eval.dataset import load_dataset
from nriqa.eval.predictors import ScorerPredictor
from nriqa.inference.scorer import Scorer, ScorerInputError
from nriqa.io.exr import read_exr
from nriqa.io.manifest import ALBEDO_FILE, read_datasets, read_manifest
from nriqa.models import create_model
from nriqa.models.unet_fast import UNetFast

REPO = Path(__file__).resolve().parents[1]


def test_pairs_carry_their_variants_albedo_pass(striped_dataset):
    records = [r for r in read_datasets(striped_dataset) if r.role != "reference"]
    pairs = load_pairs(records, albedo=True)
    for p in pairs:
        on_disk = torch.from_numpy(read_exr(Path(p.record.reference).parent / ALBEDO_FILE)).permute(2, 0, 1)
        assert torch.equal(p.albedo, on_disk)
    same_scene = [p for p in pairs if p.record.scene == pairs[0].record.scene]
    assert all(p.albedo is same_scene[0].albedo for p in same_scene)  # loaded once per variant
    assert all(p.albedo is None for p in load_pairs(records))


def test_a_missing_albedo_pass_is_one_line_naming_the_file_and_the_fix(synthetic_dataset):
    records = [r for r in read_datasets(synthetic_dataset) if r.role != "reference"]
    with pytest.raises(ValueError, match=r"albedo\.exr is missing.*data_gen\.albedo_pass") as err:
        load_pairs(records, albedo=True)
    assert "\n" not in str(err.value)


def test_the_pass_changes_no_other_draw_and_is_cut_textured_jittered_not_displayed(striped_dataset):
    kw = dict(display=MIX, albedo_p=0.5)
    plain = make_dm(striped_dataset, **kw).train_set
    ds = make_dm(striped_dataset, albedo_pass=True, **kw).train_set
    ks = list(range(24))
    for k, (x, y), (px, py) in zip(ks, ds.__getitems__(ks), plain.__getitems__(ks)):
        assert x.shape[0] == 6
        assert torch.equal(x[:3], px) and torch.equal(y, py), k  # the image and its target as without the pass
        g = item_generator(ds.seed, k)
        pair = ds.pick(g)
        noisy, ref, albedo = cut_all(pair, g, ds.patch_size, albedo_pass=True)
        ds.display.sample(g)
        seed = ds.draw(k).albedo
        if seed is not None:
            albedo = albedo * texture(seed, ds.patch_size)
        params = sample_jitter(g, hsv=ds.hsv, geometric=ds.geometric)
        assert torch.allclose(x[3:], apply_jitter(albedo, params), atol=1e-6), k


def test_validation_patches_hold_the_pass_as_it_is(synthetic_dataset, tmp_path):
    root = with_albedo(synthetic_dataset, tmp_path / "d", constant=True)
    dm = make_dm(root, albedo_pass=True)
    plain = make_dm(root)
    x, y = dm.val_set.tensors
    px, py = plain.val_set.tensors
    assert x.shape[1] == 6 and torch.equal(x[:, :3], px) and torch.equal(y, py)
    want = torch.tensor(CONSTANT).view(1, 3, 1, 1).expand_as(x[:, 3:])
    assert torch.allclose(x[:, 3:], want, atol=1e-6)  # not tone-mapped, not displayed
    shown = apply_display(want[:1], TONEMAP, 1.0)
    assert not torch.allclose(shown, want[:1], atol=1e-3)  # (which would have changed it)


def test_the_model_takes_image_and_albedo_and_refuses_other_counts():
    net = create_model("unet_fast_albedo")
    assert net.in_channels == 6 and net.albedo
    assert sum(p.numel() for p in net.parameters()) == 375_156  # unet_fast_twin's count: one more image in
    assert UNetFast(in_channels=9, albedo=True).in_channels == 9  # image, twin and albedo pass
    with pytest.raises(ValueError, match="6 \\(image \\+ albedo\\)"):
        UNetFast(in_channels=3, albedo=True)


@pytest.fixture(scope="module")
def scorer() -> Scorer:
    torch.manual_seed(0)
    return Scorer(create_model("unet_fast_albedo").eval())


def test_the_scorer_asks_for_the_pass_and_refuses_it_where_not_taken(scorer):
    image = torch.rand(3, 64, 64)
    assert scorer.needs_albedo and not scorer.needs_twin
    with pytest.raises(ScorerInputError, match="pass albedo="):
        scorer(image, hdr=False)
    with pytest.raises(ScorerInputError, match="the albedo pass is \\(32, 64\\)"):
        scorer(image, hdr=False, albedo=torch.rand(3, 32, 64))
    with pytest.raises(ScorerInputError, match="takes no albedo pass"):
        Scorer(create_model("unet_fast").eval())(image, hdr=False, albedo=torch.rand(3, 64, 64))


def test_the_scorer_feeds_the_pass_as_it_is_tiled_or_not(scorer, one_thread):
    torch.manual_seed(1)
    image, albedo = torch.rand(2, 3, 96, 80), torch.rand(2, 3, 96, 80)
    whole = scorer(image, hdr=False, albedo=albedo)
    direct = scorer.net(torch.cat([image, albedo], 1))[:, 0].clamp(0, 1)
    assert torch.allclose(whole.map, direct, atol=1e-5)
    tiled = Scorer(scorer.net, tile=32)(image, hdr=False, albedo=albedo)
    assert torch.allclose(tiled.map, whole.map, atol=1e-5)
    bad = albedo.clone()
    bad[:, :, :4, :4] = math.nan
    bad[:, :, -4:, -4:] = 7.0
    fixed = bad.nan_to_num(0.0).clamp(0, 1)
    assert torch.equal(scorer(image, hdr=False, albedo=bad).map, scorer(image, hdr=False, albedo=fixed).map)
    assert torch.isfinite(scorer(image, hdr=False, albedo=bad).score).all()


def test_the_evaluation_loads_the_pass_where_the_dataset_has_one(striped_dataset, synthetic_dataset, scorer):
    records, _ = read_manifest(striped_dataset)
    items = load_dataset(striped_dataset, records).items
    assert items and all(i.albedo is not None and i.albedo.shape == i.ldr.shape for i in items)
    assert math.isfinite(ScorerPredictor("albedo", scorer).predict(items[0]).score)
    bare = load_dataset(synthetic_dataset, read_manifest(synthetic_dataset)[0]).items
    assert bare[0].albedo is None and math.isnan(ScorerPredictor("albedo", scorer).predict(bare[0]).score)


def run_albedo_pass(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "data_gen.albedo_pass", *args], cwd=REPO, capture_output=True, text=True, timeout=600
    )


def test_the_albedo_pass_renders_beside_each_reference_and_resumes(tiny, tmp_path):
    records, _ = read_manifest(tiny)
    variants = {r.reference for r in records}
    data = tmp_path / "tiny"
    shutil.copytree(tiny, data)
    proc = run_albedo_pass(str(data), "--spp", "4")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert f"{len(variants)} albedo passes to render" in proc.stdout
    for ref in variants:
        albedo, reference = read_exr(data / Path(ref).parent / ALBEDO_FILE), read_exr(data / ref)
        assert albedo.shape == reference.shape
        assert albedo.min() >= 0.0 and albedo.max() <= 1.0 and albedo.max() > 0.05  # every scene shows a surface
    again = run_albedo_pass(str(data))
    assert again.returncode == 0 and "0 albedo passes to render" in again.stdout


def test_the_albedo_pass_refuses_a_folder_without_a_manifest_in_one_line(tmp_path):
    proc = run_albedo_pass(str(tmp_path))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.startswith("data_gen.albedo_pass: error:") and proc.stderr.count("\n") == 1


WALL = """<scene version="3.0.0">
    <default name="res" value="8"/>
    <sensor type="perspective">
        <float name="fov" value="30"/>
        <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm">
            <integer name="width" value="$res"/><integer name="height" value="$res"/><rfilter type="box"/>
        </film>
    </sensor>
    <shape type="rectangle">
        <transform name="to_world"><scale value="10"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.25, 0.5, 0.75"/></bsdf>
    </shape>
</scene>
"""


def test_the_albedo_pass_of_a_scene_file_is_its_reflectance(tmp_path):
    pytest.importorskip("mitsuba")
    (tmp_path / "wall.xml").write_text(WALL)
    proc = run_albedo_pass("--scene-file", str(tmp_path / "wall.xml"), "--out", str(tmp_path / "a.exr"), "--res", "12")
    assert proc.returncode == 0, proc.stderr[-2000:]
    albedo = read_exr(tmp_path / "a.exr")
    assert albedo.shape == (12, 12, 3)
    assert np.allclose(albedo, [0.25, 0.5, 0.75], atol=1e-4)  # a wall filling the view: its reflectance everywhere
    (tmp_path / "bad.xml").write_text('<scene version="3.0.0"><shape type="nope"/></scene>')
    for args in (["--scene-file", str(tmp_path / "bad.xml"), "--out", "x.exr"], ["--scene-file", "wall.xml"]):
        proc = run_albedo_pass(*args)
        assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr


def test_the_albedo_pass_sees_through_the_boundaries_of_media():
    """A null-BSDF boundary is invisible in the render; the pass shows what lies behind it, even from inside."""
    mi = pytest.importorskip("mitsuba")
    from data_gen.albedo_pass import albedo_scene, without_null_surfaces
    from nriqa.io.manifest import Record

    if mi.variant() is None:
        mi.set_variant("scalar_rgb")
    scene = {
        "type": "scene",
        "sensor": {"type": "perspective", "medium": {"type": "ref", "id": "fog"}},
        "fog": {"type": "homogeneous"},
        "air": {"type": "cube", "bsdf": {"type": "null"}, "interior": {"type": "ref", "id": "fog"}},
        "wall": {"type": "rectangle", "bsdf": {"type": "diffuse"}},
    }
    seen = without_null_surfaces(scene)
    assert (
        set(seen) == {"type", "sensor", "fog", "wall"}
        and "medium" not in seen["sensor"]
        and "medium" in scene["sensor"]
    )
    ref = "shafts/v000/reference.exr"
    rec = Record(
        "shafts/v000/x", "shafts", 0, "volpath_independent", "test", 4, 1, "x.exr", ref, 16, 16, 0.0, "scalar_rgb"
    )
    built = albedo_scene(rec, seed=1, spp=4)
    assert "air" not in built and "medium" not in built["sensor"] and built["integrator"]["type"] == "aov"
    image = np.array(mi.render(mi.load_dict(built), seed=0))
    assert image.max() > 0.05, "from inside the haze the pass shows the room's walls"
