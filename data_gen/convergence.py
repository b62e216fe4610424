"""Does an algorithm converge to the scene's reference? A blockwise bias test with the twin.

For the top rung's test image ``a`` and its independent twin ``b``, ``m = (a + b) / 2`` estimates
the algorithm's expected image, and ``(a - b) / 2`` has the same per-pixel variance as ``m``. The
reference is noisy too: its per-pixel variance is estimated from the reference algorithm's own
top-rung pair (same integrator and sampler) scaled by the ratio of sample counts; stratified
samplers can be as accurate at 64 spp as the independent reference at 1024, so the reference's
noise must not be guessed from the tested algorithm's. Over blocks of pixels, the mean difference
``m - reference`` divided by its standard error is a z-score: about N(0, 1) where the algorithm
converges to the reference, large where it is biased (e.g. particle tracing that never sees a
glass object). The verdict uses robust summaries of |z| so that fireflies do not decide it.

Through a pixel filter wider than a box (``pixel_filter``, data_gen's option) neighbouring pixels share
samples, so a block mean varies more than its pixels' variances say; for such images the block variance
is scaled by how much more the twin difference's block means vary than independent pixels would.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import torch

from nriqa.core.tonemap import LUMA_WEIGHTS, tonemap
from nriqa.io.exr import read_exr
from nriqa.io.manifest import Record

LUMA = np.array(LUMA_WEIGHTS, dtype=np.float64)  # thesis eq. 4.1
# The largest reference-to-test noise ratio a rung's target may be measured at: the reference
# holds at least 4x the test image's effective samples, the "visually converged" noisy references
# of thesis ch. 4 (nriqa.ch4.CONVERGED_FACTOR), where full-reference measures agree with the true one.
MAX_REFERENCE_NOISE = 0.25


@dataclasses.dataclass(frozen=True)
class Convergence:
    """Block z-scores summary: median |z|, fraction of blocks with |z| > 4, relative mean bias."""

    median_abs_z: float
    frac_outliers: float
    relative_bias: float

    @property
    def converged(self) -> bool:
        """Median |z| of N(0,1) is 0.67 and |z| > 4 has probability 6e-5.

        Caustics seen at a few spp are heavy-tailed: where both images miss a rare bright path,
        the twin underestimates the variance, so a few outlier blocks are tolerated (converging
        algorithms stay below 7% on the tiny and default presets); a biased algorithm fails on a
        larger area (particle tracing on the caustic scene: 19%).
        """
        return self.median_abs_z < 1.5 and self.frac_outliers < 0.12


def _luma(x: np.ndarray) -> np.ndarray:
    return np.asarray(x, dtype=np.float64) @ LUMA


def _blocks(x: np.ndarray, block: int) -> np.ndarray:
    h, w = (x.shape[0] // block) * block, (x.shape[1] // block) * block
    return x[:h, :w].reshape(h // block, block, w // block, block).mean(axis=(1, 3))


def pixel_variance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-pixel luminance variance of one image, from an independent pair ``(H, W, 3)``: (La - Lb)^2 / 2."""
    return (_luma(a) - _luma(b)) ** 2 / 2


def convergence(
    test: np.ndarray,
    twin: np.ndarray,
    reference: np.ndarray,
    reference_variance: np.ndarray,
    block: int = 4,
    spread: bool = False,
) -> Convergence:
    """Compare ``(H, W, 3)`` linear images; ``reference_variance`` is the reference's per-pixel ``(H, W)`` variance.

    ``spread``: the images went through a pixel filter that spreads samples over neighbours (not a box), so
    pixel noise is correlated; the block variance is scaled by :func:`block_inflation` of the twin difference.
    """
    a, b, r = _luma(test), _luma(twin), _luma(reference)
    m = (a + b) / 2
    d = _blocks(m - r, block)
    var = (_blocks(((a - b) / 2) ** 2, block) + _blocks(reference_variance, block)) / block**2
    if spread:
        var = var * block_inflation((a - b) / 2, block)
    floor = (1e-4 * max(r.mean(), 1e-6)) ** 2
    z = np.abs(d) / np.sqrt(var + floor)
    bias = abs(m.mean() - r.mean()) / max(r.mean(), 1e-6)
    return Convergence(float(np.median(z)), float((z > 4).mean()), float(bias))


def block_inflation(noise: np.ndarray, block: int) -> float:
    """How much more the block means of a zero-mean ``noise`` image vary than its pixels' variances say (>= 1).

    1 for independent pixels; through Mitsuba's Gaussian pixel filter about 2.5 for 4x4 blocks.
    """
    independent = float((_blocks(noise**2, block) / block**2).sum())
    observed = float((_blocks(noise, block) ** 2).sum())
    return max(1.0, observed / max(independent, 1e-300))


def top_rungs(records: list[Record]) -> dict[tuple[str, int, str], Record]:
    """The highest-spp test image per (scene, variant, algorithm)."""
    top: dict[tuple[str, int, str], Record] = {}
    for r in records:
        key = (r.scene, r.variant, r.algorithm)
        if r.role == "test" and (key not in top or r.spp > top[key].spp):
            top[key] = r
    return top


def _tested(records: list[Record], every_rung: bool) -> list[Record]:
    """The test images to check: each algorithm's top rung per variant, or every rung."""
    tests = [r for r in records if r.role == "test"] if every_rung else list(top_rungs(records).values())
    return sorted(tests, key=lambda r: (r.scene, r.variant, r.algorithm, r.spp))


def dataset_verdicts(root: str | Path, records: list[Record], every_rung: bool = False) -> list[dict]:
    """Convergence of every algorithm's top rung (or of every rung) in every variant of a dataset.

    The reference's variance comes from the reference algorithm's top-rung pair, which every
    scene renders (its reference algorithm is among its ladder algorithms).
    """
    root = Path(root)
    by_id = {r.id: r for r in records}
    refs = {r.path: r for r in records if r.role == "reference"}
    top = top_rungs(records)
    ref_vars: dict[tuple[str, int], np.ndarray] = {}
    rows = []
    for rec in _tested(records, every_rung):
        ref = refs[rec.reference]
        if (rec.scene, rec.variant) not in ref_vars:
            ind = top[(rec.scene, rec.variant, ref.algorithm)]
            pair = read_exr(root / ind.path), read_exr(root / by_id[ind.twin].path)
            ref_vars[(rec.scene, rec.variant)] = pixel_variance(*pair) * ind.spp / ref.spp
        c = convergence(
            read_exr(root / rec.path),
            read_exr(root / by_id[rec.twin].path),
            read_exr(root / ref.path),
            ref_vars[(rec.scene, rec.variant)],
            spread=rec.pixel_filter != "box",
        )
        rows.append(
            {
                "scene": rec.scene,
                "variant": rec.variant,
                "algorithm": rec.algorithm,
                "spp": rec.spp,
                "median_abs_z": round(c.median_abs_z, 3),
                "frac_outliers": round(c.frac_outliers, 3),
                "relative_bias": round(c.relative_bias, 4),
                "converged": c.converged,
            }
        )
    return rows


def displayed_luma(x: np.ndarray) -> np.ndarray:
    """Luminance (eq. 4.1) of the package tone map of a linear ``(H, W, 3)`` image: what the SSIM target sees."""
    ldr = tonemap(torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32)).permute(2, 0, 1)[None])[0]
    return ldr.permute(1, 2, 0).double().numpy() @ LUMA


def reference_noise_ratio(
    test: np.ndarray, twin: np.ndarray, ref_pair: tuple[np.ndarray, np.ndarray], ref_scale: float
) -> float:
    """Reference noise over test noise, summed over pixels of the displayed luminance.

    ``test``/``twin`` are a rung's independent ``(H, W, 3)`` pair; ``ref_pair`` is the reference
    algorithm's top-rung pair and ``ref_scale`` = its spp / the reference's spp, so that
    ``ref_scale * (a - b)^2 / 2`` estimates the reference's per-pixel variance. Where reference noise
    adds to the test noise in SSIM's denominator, 1 - SSIM is overstated by about this ratio.
    """
    ra, rb = (displayed_luma(x) for x in ref_pair)
    ta, tb = displayed_luma(test), displayed_luma(twin)
    test_var = float(((ta - tb) ** 2).sum() / 2)
    ref_var = float(((ra - rb) ** 2).sum() / 2) * ref_scale
    return ref_var / max(test_var, 1e-20)


def reference_noise(root: str | Path, records: list[Record]) -> list[dict]:
    """The reference-noise ratio of every rung (test image and twin) of every algorithm and variant of a dataset.

    ``ok`` is whether the ratio stays at most :data:`MAX_REFERENCE_NOISE`; a rung that fails needs a
    larger reference budget or must be dropped from the ladder.
    """
    root = Path(root)
    by_id = {r.id: r for r in records}
    refs = {r.path: r for r in records if r.role == "reference"}
    top = top_rungs(records)
    pairs: dict[tuple[str, int], tuple[np.ndarray, np.ndarray, float]] = {}
    rows = []
    for rec in sorted((r for r in records if r.role == "test"), key=lambda r: (r.scene, r.variant, r.algorithm, r.spp)):
        ref = refs[rec.reference]
        key = (rec.scene, rec.variant)
        if key not in pairs:
            ind = top[(rec.scene, rec.variant, ref.algorithm)]
            pairs[key] = (read_exr(root / ind.path), read_exr(root / by_id[ind.twin].path), ind.spp / ref.spp)
        a, b, scale = pairs[key]
        ratio = reference_noise_ratio(read_exr(root / rec.path), read_exr(root / by_id[rec.twin].path), (a, b), scale)
        rows.append(
            {
                "scene": rec.scene,
                "variant": rec.variant,
                "algorithm": rec.algorithm,
                "spp": rec.spp,
                "reference_spp": ref.spp,
                "noise_ratio": round(ratio, 4),
                "ok": ratio <= MAX_REFERENCE_NOISE,
            }
        )
    return rows


def drop_rungs(records: list[Record], rungs: list[dict]) -> list[Record]:
    """``records`` without the test images and twins of ``rungs`` (rows with scene, variant, algorithm, spp).

    What :func:`reference_noise` flags: a target measured against a reference too noisy for it is not
    trained on (thesis ch. 4). References and the other rungs stay; the files stay on disk.
    """
    gone = {(r["scene"], r["variant"], r["algorithm"], r["spp"]) for r in rungs}
    return _without(records, gone, lambda r: (r.scene, r.variant, r.algorithm, r.spp))


def _without(records: list[Record], gone: set, key) -> list[Record]:
    """``records`` without the test images and twins whose ``key(record)`` is in ``gone``; references all stay."""
    return [r for r in records if r.role == "reference" or key(r) not in gone]


def suspect_references(records: list[Record], verdicts: list[dict]) -> list[tuple[str, int]]:
    """The (scene, variant) pairs whose reference fails against its own algorithm's top rung.

    The reference and that rung come from one integrator and sampler, so they share their expected
    image: a failed verdict there says the reference itself is off (a heavy-tailed light path it
    has not averaged yet), and every target of the variant is measured against it. A failure of
    another algorithm may be that algorithm's own bias, a real property of its images.
    """
    refs = {r.path: r for r in records if r.role == "reference"}
    own = {(r.scene, r.variant): refs[r.reference].algorithm for r in records if r.role == "test"}
    bad = {
        (v["scene"], v["variant"])
        for v in verdicts
        if not v["converged"] and own.get((v["scene"], v["variant"])) == v["algorithm"]
    }
    return sorted(bad)


def drop_variants(records: list[Record], variants: list[tuple[str, int]]) -> list[Record]:
    """``records`` without the test images and twins of ``variants`` ((scene, variant) pairs).

    References stay, and so do the files on disk.
    """
    return _without(records, set(variants), lambda r: (r.scene, r.variant))


def _listed(meta: dict, key: str, dropped: list[str]) -> dict:
    """``meta`` with ``dropped`` added to its sorted list ``key`` (what earlier runs dropped stays listed)."""
    return {**meta, key: sorted({*meta.get(key, []), *dropped})}


def main(argv: list[str] | None = None) -> int:
    """``python -m data_gen.convergence DATA [--out DIR] [--every-rung] [--drop-noisy]``: both checks over a dataset.

    Writes ``verdicts.csv`` (convergence) and ``reference_noise.csv`` (every rung) to ``DIR``
    (default ``DATA/checks``), prints each failure, and exits 1 if anything failed, 2 on bad input.
    ``--drop-noisy`` rewrites the manifest without the rungs whose reference is too noisy (listed in
    its ``meta``, files kept), so that nothing trains on their targets; those rungs then count as handled.
    ``--drop-suspect`` likewise drops every test image of a variant whose reference fails against its
    own algorithm's top rung (:func:`suspect_references`); that variant's failed verdicts count as handled.
    Rerendering into DATA writes the full manifest again: run the check with ``--drop-noisy`` after it.
    """
    import argparse
    import sys

    from nriqa.io.manifest import ManifestError, read_manifest, write_manifest
    from nriqa.io.tables import write_csv

    parser = argparse.ArgumentParser(prog="python -m data_gen.convergence", description=main.__doc__.splitlines()[0])
    parser.add_argument("data", type=Path, help="dataset root (holds manifest.json)")
    parser.add_argument("--out", type=Path, default=None, help="folder for the CSV files (default: DATA/checks)")
    parser.add_argument("--every-rung", action="store_true", help="convergence of every rung, not only each top rung")
    parser.add_argument(
        "--drop-noisy", action="store_true", help="rewrite the manifest without the rungs whose reference is too noisy"
    )
    parser.add_argument(
        "--drop-suspect",
        action="store_true",
        help="rewrite the manifest without the variants whose reference fails against its own algorithm",
    )
    args = parser.parse_args(argv)
    try:
        records, meta = read_manifest(args.data)
    except ManifestError as exc:
        print(f"data_gen.convergence: error: {exc}", file=sys.stderr)
        return 2
    out = args.out or args.data / "checks"
    verdicts = dataset_verdicts(args.data, records, every_rung=args.every_rung)
    noise = reference_noise(args.data, records)
    write_csv(out / "verdicts.csv", verdicts, list(verdicts[0]))
    write_csv(out / "reference_noise.csv", noise, list(noise[0]))
    failed = [v for v in verdicts if not v["converged"]]
    noisy = [n for n in noise if not n["ok"]]
    for v in failed:
        print(
            f"not converged: {v['scene']} v{v['variant']:03d} {v['algorithm']} {v['spp']} spp "
            f"(median |z| {v['median_abs_z']}, outliers {v['frac_outliers']})"
        )
    for n in noisy:
        print(
            f"reference too noisy: {n['scene']} v{n['variant']:03d} {n['algorithm']} {n['spp']} spp "
            f"(ratio {n['noise_ratio']})"
        )
    print(
        f"wrote {out}: {len(verdicts)} verdicts ({len(failed)} not converged), "
        f"{len(noise)} rungs ({len(noisy)} with a reference too noisy, ratio > {MAX_REFERENCE_NOISE})"
    )
    kept = records
    if args.drop_noisy and noisy:
        kept = drop_rungs(kept, noisy)
        dropped = [f"{n['scene']}/v{n['variant']:03d}/{n['algorithm']}/{n['spp']}" for n in noisy]
        meta = _listed(meta, "dropped_noisy_reference", dropped)
        print(f"dropping {len(noisy)} rungs whose reference is too noisy")
        noisy = []
    suspect = suspect_references(records, verdicts)
    for scene, variant in suspect:
        print(f"reference suspect: {scene} v{variant:03d} (its own algorithm's top rung does not converge to it)")
    if args.drop_suspect and suspect:
        gone = set(suspect)
        kept = drop_variants(kept, suspect)
        dropped = [f"{scene}/v{variant:03d}" for scene, variant in suspect]
        meta = _listed(meta, "dropped_suspect_reference", dropped)
        print(f"dropping the test images of {len(suspect)} variants whose reference is suspect")
        failed = [v for v in failed if (v["scene"], v["variant"]) not in gone]
    if len(kept) != len(records):
        write_manifest(args.data, kept, meta)
        print(f"rewrote {args.data / 'manifest.json'}: {len(records) - len(kept)} images dropped")
    return 1 if failed or noisy else 0


if __name__ == "__main__":
    raise SystemExit(main())
