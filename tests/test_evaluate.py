"""Evaluation: correlations and MAE on constructed predictors, the CLI, and external folders."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from nriqa.core.display import Display, apply_display, key_exposure
from nriqa.core.ssim import ssim_map
from nriqa.eval.baselines import Item, Prediction, Predictor
from nriqa.eval.dataset import load_dataset, records_of
from nriqa.eval.evaluate import main, run_predictors, summarise
from nriqa.io.exr import read_exr, write_exr
from nriqa.io.external import ExternalError, import_external, scan_external
from nriqa.io.imread import load_ldr as load_display
from nriqa.io.manifest import read_manifest


class Oracle(Predictor):
    """Predicts the true score and map exactly (optionally as a scaled, inverted raw score)."""

    fitted = False

    def __init__(self, data, name="oracle", scale="ssim", factor=1.0):
        self.data, self.name, self.scale, self.factor = data, name, scale, factor
        self.higher_is_better = factor > 0

    def predict(self, item: Item) -> Prediction:
        return Prediction(self.factor * item.true, self.factor * self.data.true_maps[item.record.id])


def _save_checkpoint(path: Path, net: torch.nn.Module, spec: dict | None = None) -> Path:
    """A minimal training checkpoint of ``net`` (what :func:`load_net_from_checkpoint` reads) at ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {f"net.{k}": v for k, v in net.state_dict().items()}
    torch.save({"hyper_parameters": {"net": spec or {"name": "fcnn_fast"}}, "state_dict": state}, path)
    return path


@pytest.fixture(scope="module")
def data(synthetic_dataset):
    root, records = records_of(synthetic_dataset)
    return load_dataset(root, records)


def test_perfect_predictor_gives_correlation_one_and_mae_zero(data):
    predictors = [Oracle(data), Oracle(data, "inverted_raw", "raw", -5.0)]
    scenes = ["alpha", "beta", "gamma"]
    rows, pixels, _ = run_predictors(data, predictors, scenes)
    comparison, per_scene = summarise(rows, pixels, predictors, scenes)
    for row in comparison + per_scene:
        assert row["pcc"] == pytest.approx(1.0, abs=1e-9) and row["srocc"] == pytest.approx(1.0, abs=1e-6)
        assert row["tau"] == pytest.approx(1.0) and row["pixel_pcc"] == pytest.approx(1.0, abs=1e-6)
    assert comparison[0]["mae"] == pytest.approx(0.0, abs=1e-12)
    assert comparison[0]["bias"] == pytest.approx(0.0, abs=1e-12)
    assert comparison[1]["mae"] < 0.05  # logistic map fitted on the other scenes


def test_bias_is_the_mean_signed_error_and_mae_its_absolute_mean(data):
    class Offset(Oracle):
        def predict(self, item):  # 0.05 too good at odd spp, 0.05 too bad at even spp
            shift = 0.05 - 0.1 * (item.record.spp % 2 == 0)
            return Prediction(item.true + shift, self.data.true_maps[item.record.id] + shift)

    offset = Offset(data, "offset")
    rows, pixels, _ = run_predictors(data, [offset], ["alpha"])
    (pooled,), per_scene = summarise(rows, pixels, [offset], ["alpha"])
    err = np.array([r["predicted"] - r["true"] for r in rows])
    assert set(np.round(err, 6)) <= {0.05, -0.05} and len(set(np.round(err, 6))) == 2
    assert pooled["bias"] == pytest.approx(err.mean(), abs=1e-9) and pooled["mae"] == pytest.approx(0.05, abs=1e-9)
    assert per_scene[0]["bias"] == pytest.approx(pooled["bias"])


def test_cli_writes_tables_and_figures(synthetic_dataset, tmp_path):
    main([str(synthetic_dataset), "--out", str(tmp_path), "--baselines", "all", "--scenes", "beta"])
    for name in (
        "comparison.csv",
        "comparison.md",
        "per_scene.md",
        "images.csv",
        "scatter.png",
        "maps_dual_buffer_beta.png",
        "monotone.md",
        "monotone.csv",
        "by_spp.md",
        "by_spp.csv",
    ):
        assert (tmp_path / name).is_file(), name
    table = (tmp_path / "comparison.md").read_text()
    for name in ("wavelet_sigma", "laplacian", "niqe", "brisque", "dual_buffer"):
        assert f"| {name} |" in table
    assert "alpha" not in (tmp_path / "per_scene.md").read_text().split("\n", 3)[-1]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--scenes", "nowhere"], "unknown scene(s) nowhere"),
        (["--baselines", "nope"], "unknown baseline 'nope'"),
        (["--baselines", "none"], "nothing to evaluate"),
    ],
)
def test_cli_user_errors_are_one_line(synthetic_dataset, tmp_path, capsys, args, message):
    with pytest.raises(SystemExit) as exc:
        main([str(synthetic_dataset), "--out", str(tmp_path), *args])
    assert str(exc.value).startswith("error: ") and message in str(exc.value) and "\n" not in str(exc.value)


# --- external folders -----------------------------------------------------------------------


def _png(path: Path, value: float, noise: float, seed: int, size: int = 32) -> None:
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size] / size
    img = value * (0.6 + 0.3 * np.sin(6 * xx)[..., None] * np.cos(5 * yy)[..., None]) + rng.normal(
        0, noise, (size, size, 3)
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray((np.clip(img, 0, 1) * 255).round().astype(np.uint8)).save(path)


@pytest.fixture()
def external(tmp_path) -> Path:
    root = tmp_path / "renders"
    for k, scene in enumerate(("room", "car")):
        _png(root / scene / "reference.png", 0.8, 0.0, 0)
        for spp in (1, 4, 16):
            _png(root / scene / f"bdpt - {spp}.png", 0.8, 0.2 / math.sqrt(spp), 10 * k + spp)
    return root


def test_external_folder_parses_names_and_references(external):
    records = scan_external(external)
    refs = [r for r in records if r.role == "reference"]
    tests = sorted((r.scene, r.algorithm, r.spp) for r in records if r.role == "test")
    assert sorted(r.path for r in refs) == ["car/reference.png", "room/reference.png"]
    assert tests == [(s, "bdpt", n) for s in ("car", "room") for n in (1, 4, 16)]
    assert all(r.reference == f"{r.scene}/reference.png" and r.width == 32 and r.twin is None for r in records)


def test_external_highest_spp_reference_and_seed_twins(tmp_path):
    root = tmp_path / "r"
    for spp in (2, 8, 1024):
        for seed in (1, 2):
            _png(root / "s" / f"pt - {spp} - {seed}.png", 0.5, 0.1, spp + seed)
    records = scan_external(root, pattern="{scene}/{algorithm} - {spp} - {seed}", reference="highest:pt")
    ref = [r for r in records if r.role == "reference"][0]
    assert ref.path.startswith("s/pt - 1024")
    tests = [r for r in records if r.role == "test"]
    assert sorted(r.spp for r in tests) == [2, 8, 1024]
    # seeds pair up as twins; the reference's partner at 1024 spp stays as a test image without twin
    assert [bool(r.twin) for r in sorted(tests, key=lambda r: r.spp)] == [True, True, False]
    assert not any(r.path == ref.path for r in records if r.role != "reference")


def test_an_albedo_pass_beside_a_reference_is_not_a_test_image(external):
    before = scan_external(external)
    write_exr(external / "room" / "albedo.exr", np.full((32, 32, 3), 0.5, np.float32))
    assert scan_external(external) == before
    write_exr(external / "albedo.exr", np.full((32, 32, 3), 0.5, np.float32))  # beside no reference: a stray file
    with pytest.raises(ExternalError, match="name does not match pattern"):
        scan_external(external)


def test_external_png_is_display_referred_and_exr_tone_mapped(tmp_path):
    Image.fromarray(np.full((8, 8, 3), 128, np.uint8)).save(tmp_path / "a.png")
    assert float(load_display(tmp_path / "a.png").mean()) == pytest.approx(128 / 255)
    write_exr(tmp_path / "b.exr", np.ones((8, 8, 3), np.float32))
    assert float(load_display(tmp_path / "b.exr").mean()) == pytest.approx(0.5 ** (1 / 2.2), abs=1e-4)


@pytest.mark.parametrize(
    "setup, message",
    [
        (lambda r: _png(r / "room" / "bdpt_16.png", 0.5, 0.1, 1), "name does not match pattern"),
        (lambda r: (r / "car" / "reference.png").unlink(), "scene 'car' has no reference matching 'car/reference.*'"),
        (lambda r: _png(r / "car" / "reference.jpg", 0.5, 0.0, 1), "matches 2 files"),
    ],
)
def test_external_errors(external, setup, message):
    setup(external)
    with pytest.raises(ExternalError, match=message.replace("(", r"\(").replace("*", r"\*").replace(".", r"\.")):
        scan_external(external)


def test_external_manifest_and_evaluation(external, tmp_path):
    out = tmp_path / "ds"
    import_external(external, out)
    records, meta = read_manifest(out)
    assert meta["pattern"] == "{scene}/{algorithm} - {spp}" and len(records) == 8
    assert (out / records[0].path).resolve().is_file()
    main([str(external), "--out", str(tmp_path / "ev"), "--baselines", "wavelet_sigma,dual_buffer", "--no-figures"])
    table = (tmp_path / "ev" / "comparison.md").read_text()
    assert "| wavelet_sigma | raw |  | 6 |" in table and "| dual_buffer | ssim |  | 0 |" in table


def test_square_spp_counts_images_at_the_count_rendered(tmp_path):
    """--square-spp: asked for 2, 4 and 8 samples, a square sampler rendered 4, 4 and 16: two rungs, not three."""
    import csv

    root = tmp_path / "renders"
    _png(root / "room" / "reference.png", 0.8, 0.0, 0)
    for spp in (2, 4, 8):
        _png(root / "room" / f"ld - {spp}.png", 0.8, 0.2 / math.sqrt(spp), spp)
    args = [str(root), "--baselines", "dual_buffer", "--no-figures"]
    main([*args, "--out", str(tmp_path / "asked")])
    main([*args, "--out", str(tmp_path / "rendered"), "--square-spp", "l*"])

    def read(name, table):
        with open(tmp_path / name / table, newline="") as f:
            return list(csv.DictReader(f))

    assert sorted(int(r["spp"]) for r in read("asked", "images.csv")) == [2, 4, 8]
    assert sorted(int(r["spp"]) for r in read("rendered", "images.csv")) == [4, 4, 16]
    assert [int(r["rungs"]) for r in read("asked", "monotone.csv")] == [3]
    assert [int(r["rungs"]) for r in read("rendered", "monotone.csv")] == [2]


def test_learned_scorer_as_predictor(data):
    from nriqa.eval.predictors import ScorerPredictor
    from nriqa.inference.scorer import Scorer
    from nriqa.models import create_model

    torch.manual_seed(0)
    p = ScorerPredictor("fcnn_fast_random", Scorer(create_model("fcnn_fast")))
    assert p.scale == "ssim" and p.higher_is_better
    rows, pixels, maps = run_predictors(data, [p], ["alpha"])
    assert len(rows) == 4 and all(0.0 <= r["predicted"] <= 1.0 for r in rows)
    assert ("fcnn_fast_random", "alpha") in pixels and next(iter(maps.values())).shape == (80, 80)


def test_checkpoint_names_are_short_and_distinct():
    from nriqa.eval.predictors import checkpoint_names

    assert checkpoint_names(["runs/a/checkpoints/last.ckpt", "runs/b/checkpoints/last.ckpt"]) == ["a/last", "b/last"]
    assert checkpoint_names(["x/best.ckpt"]) == ["best"]


def test_crossval_run_scores_each_scene_with_the_fold_that_held_it_out(data, tmp_path):
    from nriqa.eval.dataset import EvaluationError
    from nriqa.eval.predictors import CrossvalPredictor
    from nriqa.inference.scorer import Scorer
    from nriqa.models import create_model

    nets = {}
    for seed, scene in enumerate(["alpha", "beta"]):
        torch.manual_seed(seed)
        nets[scene] = create_model("fcnn_fast").eval()
        _save_checkpoint(tmp_path / "run" / "folds" / scene / "checkpoints" / "last.ckpt", nets[scene])
    p = CrossvalPredictor(tmp_path / "run")
    assert p.name == "run-cv" and p.scale == "ssim"
    rows, _, _ = run_predictors(data, [p], ["alpha", "beta"])
    for scene in ("alpha", "beta"):
        item = next(it for it in data.items if it.record.scene == scene)
        expected = Scorer(nets[scene])(item.ldr, hdr=False).score
        got = next(r["predicted"] for r in rows if r["id"] == item.record.id)
        assert got == pytest.approx(expected, abs=1e-6)
    with pytest.raises(EvaluationError, match="no fold holds scene gamma out"):
        run_predictors(data, [p], ["gamma"])
    with pytest.raises(EvaluationError, match="run nriqa-crossval first"):
        CrossvalPredictor(tmp_path / "nothing")


def test_window_reaches_the_folds_and_checkpoints(data, tmp_path):
    """``--window``: fold and checkpoint networks read the (80x80) images in pieces of that side."""
    from nriqa.eval.predictors import build_predictors
    from nriqa.inference.scorer import Scorer
    from nriqa.models import create_model

    torch.manual_seed(0)
    net = create_model("unet_fast", width=8, depth=1).eval()
    spec = {"name": "unet_fast", "width": 8, "depth": 1}
    for scene in ("alpha", "beta"):
        ckpt = _save_checkpoint(tmp_path / "run" / "folds" / scene / "checkpoints" / "last.ckpt", net, spec)
    run, ckpt = str(tmp_path / "run"), str(ckpt)
    windowed = build_predictors([], [ckpt], "none", [run], window=32)
    assert all(s.window == 32 for s in windowed[0].scorers.values()) and windowed[1].scorer.window == 32
    rows, _, _ = run_predictors(data, windowed[:1], ["alpha"])
    whole, _, _ = run_predictors(data, build_predictors([], [], "none", [run])[:1], ["alpha"])
    item = next(it for it in data.items if it.record.scene == "alpha")
    got = next(r["predicted"] for r in rows if r["id"] == item.record.id)
    assert got == pytest.approx(Scorer(net, window=32)(item.ldr, hdr=False).score, abs=1e-6)
    assert got != pytest.approx(next(r["predicted"] for r in whole if r["id"] == item.record.id), abs=1e-6)


def test_overlap_adds_a_blended_row_for_each_windowed_scorer(data, tmp_path):
    """``--overlap``: a windowed checkpoint is scored twice (side by side, then blended, ``NAME-overlap``);
    a model not read in windows gets no second row."""
    from nriqa.eval.predictors import build_predictors
    from nriqa.inference.scorer import Scorer
    from nriqa.models import create_model

    torch.manual_seed(0)
    spec = {"name": "unet_fast", "width": 8, "depth": 1, "window": 32}
    net = create_model(**spec).eval()
    windowed = _save_checkpoint(tmp_path / "u" / "checkpoints" / "last.ckpt", net, spec)
    plain = _save_checkpoint(tmp_path / "f" / "checkpoints" / "last.ckpt", create_model("fcnn_fast").eval())
    predictors = build_predictors([], [str(windowed), str(plain)], "none", overlap=True)
    assert [p.name for p in predictors] == ["u/last", "f/last", "u/last-overlap"]
    assert not predictors[0].scorer.overlap and predictors[2].scorer.overlap
    rows, _, _ = run_predictors(data, predictors, ["alpha"])
    item = next(it for it in data.items if it.record.scene == "alpha")
    got = {r["predictor"]: r["predicted"] for r in rows if r["id"] == item.record.id}
    assert got["u/last-overlap"] == pytest.approx(Scorer(net, overlap=True)(item.ldr, hdr=False).score, abs=1e-6)
    assert got["u/last-overlap"] != pytest.approx(got["u/last"], abs=1e-6)


def test_checkpoints_joined_with_plus_score_with_the_mean_of_their_maps(data, tmp_path):
    from nriqa.eval.predictors import build_predictors
    from nriqa.inference.scorer import Scorer
    from nriqa.models import create_model

    nets, paths = [], []
    for seed in (0, 1):
        torch.manual_seed(seed)
        nets.append(create_model("fcnn_fast").eval())
        paths.append(_save_checkpoint(tmp_path / f"s{seed}" / "checkpoints" / "last.ckpt", nets[-1]))
    pair, single = build_predictors([], [f"{paths[0]}+{paths[1]}", str(paths[0])], "none")
    assert pair.name == "s0/last+s1/last" and single.name == "s0/last"
    rows, _, _ = run_predictors(data, [pair, single], ["alpha"])
    item = next(it for it in data.items if it.record.scene == "alpha")
    maps = [Scorer(net)(item.ldr, hdr=False).map for net in nets]
    got = {r["predictor"]: r["predicted"] for r in rows if r["id"] == item.record.id}
    assert got[pair.name] == pytest.approx(float(np.clip((maps[0] + maps[1]) / 2, 0, 1).mean()), abs=1e-5)
    assert got[single.name] == pytest.approx(float(np.clip(maps[0], 0, 1).mean()), abs=1e-5)
    assert got[pair.name] != pytest.approx(got[single.name], abs=1e-4)
    plus = tmp_path / "a+b.ckpt"  # a file whose name holds "+" is one checkpoint
    plus.write_bytes(paths[0].read_bytes())
    assert build_predictors([], [str(plus)], "none")[0].name == "a+b"


def test_evaluation_on_the_tiny_preset(tiny, tmp_path):
    main(
        [
            str(tiny),
            "--out",
            str(tmp_path),
            "--baselines",
            "wavelet_sigma,laplacian,dual_buffer_corrected",
            "--no-figures",
        ]
    )
    rows = {r.split(",")[0]: r.split(",") for r in (tmp_path / "comparison.csv").read_text().splitlines()[1:]}
    assert set(rows) == {"wavelet_sigma", "laplacian", "dual_buffer_corrected"}
    header = (tmp_path / "comparison.csv").read_text().splitlines()[0].split(",")
    srocc = float(rows["dual_buffer_corrected"][header.index("srocc")])
    assert srocc > 0.9, "the twin-based estimate ranks the tiny preset's images nearly perfectly"


def test_crossval_runs_joined_with_plus_score_with_the_mean_of_their_folds(data, tmp_path):
    from nriqa.eval.dataset import EvaluationError
    from nriqa.eval.predictors import CrossvalPredictor
    from nriqa.inference.scorer import Scorer
    from nriqa.models import create_model

    nets = {}
    for seed, run in enumerate(["s0", "s1"]):
        torch.manual_seed(seed)
        nets[run] = create_model("fcnn_fast").eval()
        for scene in ("alpha", "beta") if run == "s0" else ("alpha",):
            _save_checkpoint(tmp_path / run / "folds" / scene / "checkpoints" / "last.ckpt", nets[run])
    p = CrossvalPredictor(f"{tmp_path / 's0'}+{tmp_path / 's1'}")
    assert p.name == "s0+s1-cv" and set(p.scorers) == {"alpha"}  # only the scenes both runs hold out
    rows, _, _ = run_predictors(data, [p], ["alpha"])
    item = next(it for it in data.items if it.record.scene == "alpha")
    maps = [Scorer(nets[r])(item.ldr, hdr=False).map for r in ("s0", "s1")]
    got = next(r["predicted"] for r in rows if r["id"] == item.record.id)
    assert got == pytest.approx(float(np.clip((maps[0] + maps[1]) / 2, 0, 1).mean()), abs=1e-5)
    with pytest.raises(EvaluationError, match="no fold holds scene beta out"):
        run_predictors(data, [p], ["beta"])
    (tmp_path / "s0").rename(tmp_path / "a+b")  # a run folder whose name holds "+" is one run
    assert set(CrossvalPredictor(tmp_path / "a+b").scorers) == {"alpha", "beta"}


def test_display_shows_image_twin_and_reference_alike_and_measures_after_it(synthetic_dataset):
    root, records = records_of(synthetic_dataset)
    display = Display.parse("srgb+1:8")
    shown = load_dataset(root, records, display=display)
    item = next(it for it in shown.items if it.record.scene == "beta" and it.record.spp == 4)
    linear = {
        p: torch.from_numpy(read_exr(root / p)).permute(2, 0, 1) for p in (item.record.path, item.record.reference)
    }
    twin_path = next(r.path for r in records if r.id == item.record.twin)
    key = key_exposure(linear[item.record.reference])
    ref = apply_display(linear[item.record.reference], display, key)
    assert torch.equal(shown.refs[item.record.reference], ref)
    assert torch.equal(item.ldr, apply_display(linear[item.record.path], display, key))
    twin = apply_display(torch.from_numpy(read_exr(root / twin_path)).permute(2, 0, 1), display, key)
    assert torch.equal(item.twin, twin)
    assert item.true == pytest.approx(float(ssim_map(item.ldr[None], ref[None]).mean()), abs=1e-7)
    tone_mapped = load_dataset(root, records)
    same = next(it for it in tone_mapped.items if it.record.id == item.record.id)
    assert item.true != pytest.approx(same.true, abs=1e-3)  # the display changes the truth


def test_cli_display_names_itself_and_plain_tone_map_changes_nothing(synthetic_dataset, tmp_path):
    base = [str(synthetic_dataset), "--baselines", "dual_buffer", "--no-figures"]
    main([*base, "--out", str(tmp_path / "plain")])
    main([*base, "--out", str(tmp_path / "tonemap"), "--display", "tonemap"])
    main([*base, "--out", str(tmp_path / "srgb"), "--display", "gamma22-1"])
    assert (tmp_path / "plain" / "images.csv").read_text() == (tmp_path / "tonemap" / "images.csv").read_text()
    assert (tmp_path / "plain" / "images.csv").read_text() != (tmp_path / "srgb" / "images.csv").read_text()
    assert "display `gamma22-1`" in (tmp_path / "srgb" / "comparison.md").read_text()


@pytest.mark.parametrize("display, message", [("log", "CURVE[+-STOPS][:BITS]"), ("srgb", "needs linear EXR renders")])
def test_cli_display_errors_are_one_line(external, tmp_path, display, message):
    with pytest.raises(SystemExit) as exc:
        main([str(external), "--out", str(tmp_path / "ev"), "--display", display, "--baselines", "dual_buffer"])
    assert str(exc.value).startswith("error: ") and message in str(exc.value) and "\n" not in str(exc.value)
    assert not (tmp_path / "ev" / "comparison.md").exists()


def test_by_spp_bands_hold_each_image_once_with_its_error():
    from nriqa.eval.by_spp import by_spp

    rows = [
        {"predictor": "p", "spp": spp, "true": 0.5, "mapped": 0.5 + shift, "predicted": 0.0}
        for spp, shift in ((2, 0.1), (8, 0.3), (16, -0.2), (1024, 0.0), (1024, math.nan))
    ]
    bands = {b["spp"]: b for b in by_spp(rows, ["p"])}
    assert list(bands) == ["1-8", "9-64", ">=65"]
    assert (
        bands["1-8"]["n"] == 2
        and bands["1-8"]["bias"] == pytest.approx(0.2)
        and bands["1-8"]["mae"] == pytest.approx(0.2)
    )
    assert bands["9-64"]["bias"] == pytest.approx(-0.2) and bands["9-64"]["mae"] == pytest.approx(0.2)
    assert bands[">=65"]["n"] == 1 and bands[">=65"]["bias"] == 0.0  # a NaN score is left out, not averaged in
    assert by_spp(rows, ["other"]) == []


def test_shipped_scorers_rows_carry_their_interval_and_the_tables_its_coverage(synthetic_dataset, tmp_path):
    """Each row gets the ends of the scorer's calibrated interval (the LDR one through another display);
    coverage and width are their share and mean over the rows; scorers without a calibration get none."""
    import csv

    from nriqa.inference.scorer import Scorer

    base = [str(synthetic_dataset), "--baselines", "wavelet_sigma", "--no-figures", "--model", "unet_fast"]
    main([*base, "--out", str(tmp_path / "plain")])
    main([*base, "--out", str(tmp_path / "srgb"), "--display", "srgb"])
    scorer = Scorer.from_pretrained()
    for name, tonemapped in (("plain", True), ("srgb", False)):
        rows = list(csv.DictReader((tmp_path / name / "images.csv").open()))
        own = [r for r in rows if r["predictor"] == "unet_fast"]
        mapped = np.array([float(r["mapped"]) for r in own])
        low, high = scorer.interval_ends(mapped, [tonemapped] * len(own))
        assert np.allclose([float(r["low"]) for r in own], low) and np.allclose([float(r["high"]) for r in own], high)
        assert all(r["low"] == "" or r["low"] == "nan" for r in rows if r["predictor"] == "wavelet_sigma")
        true = np.array([float(r["true"]) for r in own])
        table = {r["predictor"]: r for r in csv.DictReader((tmp_path / name / "comparison.csv").open())}
        assert float(table["unet_fast"]["coverage"]) == pytest.approx(((low <= true) & (true <= high)).mean())
        assert float(table["unet_fast"]["width"]) == pytest.approx((high - low).mean())
