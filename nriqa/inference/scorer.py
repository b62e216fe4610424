"""The Scorer: one object from an image to its predicted quality map and pooled score.

Load weights -> sanitise -> tone map (HDR only) -> (tiled) forward -> map + mean-pooled score.
Every consumer (``predict.py``, the render loops, evaluation) goes through it, so the
preprocessing is the training one: :func:`nriqa.core.tonemap.tonemap` on linear HDR, nothing on LDR.

Examples:
    >>> scorer = Scorer.from_pretrained("fcnn_fast")        # doctest: +SKIP
    >>> result = scorer(hdr_image)                          # doctest: +SKIP  (H, W, 3) float32
    >>> result.map.shape, result.score                      # doctest: +SKIP
    ((480, 640), 0.87)
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping

import numpy as np
import torch
from torch import Tensor, nn

from nriqa.core.ssim import FLAT_ROWS, WINDOW, flat_windows, may_be_flat
from nriqa.core.tonemap import tonemap
from nriqa.errors import NriqaError
from nriqa.inference.folding import fold_batchnorm
from nriqa.inference.interval import LOOP_KINDS, ScoreInterval, loop_card_key
from nriqa.inference.spread import SpreadInterval, score_spread, view_scores

__all__ = ["PIXEL_FILTERS", "Scorer", "ScoreResult", "ScorerInputError", "device_problem"]

# The pixel (reconstruction) filters a scorer can have learnt renders through: "box", each sample counted for
# its own pixel (every in-house dataset), and "gaussian", Mitsuba's film default (standard deviation 0.5 pixel).
PIXEL_FILTERS = ("box", "gaussian")


class ScorerInputError(NriqaError):
    """An image the scorer refuses (wrong shape, too small, wrong type); the message says why."""


@dataclasses.dataclass(frozen=True)
class ScoreResult:
    """What :class:`Scorer` returns.

    Attributes:
        map: predicted quality per pixel, ``(H, W)`` for one image or ``(B, H, W)`` for a batch;
            a ``numpy.ndarray`` for numpy input, a ``torch.Tensor`` (on the input's device) for torch input.
        score: the mean of the map: a ``float`` for one image, ``(B,)`` (array or tensor) for a batch.
        quantity: ``"ssim"`` (map models: predicted SSIM in [0, 1], higher is better) or ``"mae"``
            (the patch model: predicted mean absolute error of the tone-mapped image, lower is better).
        hdr: whether each image was treated as linear HDR and tone-mapped (a bool, or a list for a batch).
        low, high: where the true mean SSIM lies, at the level of the scorer's calibrated
            :class:`~nriqa.inference.interval.ScoreInterval` (shipped weights carry one on their card:
            90 %, measured coverage there); like ``score`` in type and shape, ``None`` without a calibration.
            With ``spread`` and a spread interval (for HDR, or for LDR input), its ends instead.
        spread: with ``Scorer(..., spread=True)``, the standard deviation of the score over the image's eight
            flips and turns (:mod:`nriqa.inference.spread`), like ``score`` in type and shape; else ``None``.
    """

    map: np.ndarray | Tensor
    score: float | np.ndarray | Tensor
    quantity: str
    hdr: bool | list[bool]
    low: float | np.ndarray | Tensor | None = None
    high: float | np.ndarray | Tensor | None = None
    spread: float | np.ndarray | Tensor | None = None


class Scorer:
    """Predict a quality map and a pooled score for rendered images, deterministically.

    Args:
        net: a registered model (:mod:`nriqa.models`) with ``output`` ``"map"`` (predicts an SSIM
            map, thesis ch. 5 experiment II) or ``"patch"`` (predicts the MAE of a 32x32 patch,
            experiment I). The Scorer runs a copy in eval mode with batch norm folded into the
            convolutions (:func:`nriqa.inference.folding.fold_batchnorm`); ``net`` itself is not changed,
            and weights it learns later are not seen (make a new Scorer).
        tile: side of the square output tiles a map model is run on, a multiple of its ``align``
            (rounded up if not). Images whose sides are both at most ``tile`` go in one forward;
            ``0`` never tiles. For the patch model it caps the windows per forward at ``tile * 4``.
        stride: step in pixels between the 32x32 windows of the patch model (ignored for map models).
        window: side of the independent windows a context model reads a larger image in (``None``: what
            the network states, ``net.window``; ``0``: one piece). See "Windows" below.
        overlap: read the windows at half-window steps and blend them with tent weights, so the map
            has no seams on the window grid (about 4x the work on a large image; ``False``: windows
            side by side). Ignored for a model not read in windows (its maps have no seams).
        device: where the network runs (default: where its parameters are).
        interval: a calibrated :class:`~nriqa.inference.interval.ScoreInterval` for the pooled score;
            results then carry ``low`` and ``high``. :meth:`from_pretrained` passes the one on the weights'
            card (``score_interval``). It was measured for the scorer as shipped (windows side by side, the
            flat rule on); with other settings its coverage is not measured.
        ldr_interval: the interval for images taken as LDR (display-referred input, e.g. PNGs from other
            pipelines), if it was calibrated apart (card ``score_interval_ldr``); ``None``: ``interval``
            serves both.
        loop_intervals: intervals calibrated on the rows of render loops, by loop kind (``"uniform"``:
            samples spread evenly; ``"adaptive"``: placed by the scorer's map), for the score a loop
            rates (a two-buffer scorer's: the halves' score carried to the whole image). The loops'
            sure stops use their low end where one is given (card ``score_interval_loop_uniform`` /
            ``_adaptive``); other kinds keep the result's ``low``. Results of a call do not change.
        spread: also score the image's eight flips and turns and return the score's spread over them
            (:mod:`nriqa.inference.spread`; eight passes of the network instead of one); single-image SSIM map
            models only. The score stays the plain view's.
        spread_interval: with ``spread``, the interval for images taken as HDR whose offsets scale with the
            spread (card ``score_interval_spread``), which then replaces ``interval`` for them.
        spread_ldr_interval: the same for images taken as LDR (card ``score_interval_spread_ldr``), replacing
            ``ldr_interval`` for them.
        pixel_filter: the pixel filter of the renders the network learnt to read (:data:`PIXEL_FILTERS`):
            ``"box"`` (each sample counted for its own pixel; every shipped file but one) or ``"gaussian"``
            (Mitsuba's film default, e.g. ``unet_fast_gaussian``). :meth:`from_pretrained` takes it from the
            card (``pixel_filter``; ``"box"`` where it says none). The Scorer cannot see a render's filter, so
            it reads any image as if it had this one; the render loops check the scene's film against it.

    Input (``__call__``): numpy ``(H, W, 3)`` or ``(B, H, W, 3)``, torch ``(3, H, W)`` or
    ``(B, 3, H, W)``; grayscale ``(H, W)`` (or one channel) is replicated to RGB, a fourth (alpha)
    channel is dropped. Floats of any precision or ``uint8``/``uint16`` (divided by 255/65535, LDR).

    HDR or LDR, per image, when ``hdr=None``: an image with any value above 1 (``+inf`` included)
    is linear HDR and goes through :func:`nriqa.core.tonemap.tonemap`; an image within [0, 1] is taken
    as display-referred LDR and used as is. A dim linear render that happens to stay below 1 is
    therefore taken as LDR: pass ``hdr=True`` for renders (``predict.py`` does for EXR files).

    Sanitising policy (the input is a render, so bad pixels are expected; the score is never NaN):

    * HDR: exactly the tone map's policy -- NaN -> 0, negative and ``-inf`` -> 0, finite values
      clamped to 1e30 (so huge values are white), a pixel with a ``+inf`` channel -> white.
    * LDR: NaN -> 0, negative -> 0, ``+inf`` and values above 1 (only possible with ``hdr=False``)
      -> 1, i.e. the same outcome as the HDR path for the same bad pixel.
    * Images smaller than the model's window (its receptive field: ``fcnn`` 9, ``fcnn_fast`` 14,
      ``patch_cnn`` 32 px; a context model's ``min_size``: ``unet_fast`` 32) on either side are refused
      with :class:`ScorerInputError`: padding would make up most of what the network sees, and the
      SSIM the map predicts is itself undefined below 6x6 pixels.

    Two-buffer models (``needs_twin``, e.g. ``dual_fast``) take the image and an independent
    render of it at the same spp (``twin=``); both go through the same preprocessing. Models with the
    albedo pass (``needs_albedo``, e.g. ``unet_fast_albedo``) take the scene's albedo pass
    (``albedo=``): reflectances, NaN -> 0 and clamped to [0, 1], never tone-mapped.

    Maps: a map model's output is clipped to [0, 1] (the range of its SSIM target). The patch model
    gets a map by sliding 32x32 windows with ``stride`` over the image (the last window in each
    direction is moved in to touch the border, so every pixel is covered); each window's predicted
    MAE is spread over its pixels, and each pixel takes the average over the windows that cover it.

    Tiling: a map model's output at a pixel depends only on the input within half its receptive
    field, so each output tile is computed from an input tile grown by a halo of
    ``ceil(receptive_field / 2)`` rounded up to ``align``, with tile starts at multiples of
    ``align``, and the halo is cut from the output: tiled maps equal untiled ones to float
    rounding (~1e-6). Memory then depends on the tile, not the image (see ``benchmarks/scorer.py``).

    Windows: a context model that learnt from images of one size (``net.window``, e.g. ``unet_fast``
    trained on whole 64x64 renders) reads larger images in independent windows of that side, as it
    saw them in training, instead of in one piece whose context it never met. Windows start at
    multiples of ``window`` from the top-left corner; the last in each direction is moved in to touch
    the border and overlapping pixels take the mean. ``window=0`` turns this off (one piece, tiled as
    below); a map is then smooth across window borders, but a large image is read out of the model's
    training regime (docs/results/evaluation.md measures both). Side by side, neighbouring windows are
    read apart, so the map can step on the window grid. ``overlap=True`` reads windows every half window
    and weighs each pixel of a window by a tent, ``min(i + 1/2, side - i - 1/2)`` along each axis (largest
    at the window's centre, near 0 at its edge), dividing by the sum of the weights: two overlapping tents
    sum to a constant, so each window fades out where the next fades in and the map is seamless.

    Flat bright windows (map models, ``exact_flat=True``): a pixel whose whole 11x11 SSIM window is one
    colour in the prepared input, of luminance >= 0.1 (a light or constant background seen directly, a
    blown-out highlight, an overexposed PNG), is scored 1 (:func:`nriqa.core.ssim.flat_windows`). A
    Monte Carlo render is that flat only where every sample returned the same radiance, so the
    reference is the same there and the SSIM is exactly 1; the networks read such pixels lower
    (``unet_fast`` 0.94-0.99; docs/scoring.md). Black windows are left to the network (in a noisy
    render they are most often unreached, not converged). ``exact_flat=False`` returns the network's
    map unchanged.

    Inference runs in ``torch.inference_mode()`` and eval mode (no dropout, batch-norm running
    statistics): the same input gives the same map.
    """

    def __init__(
        self,
        net: nn.Module,
        *,
        tile: int = 512,
        stride: int = 8,
        window: int | None = None,
        device: str | torch.device | None = None,
        exact_flat: bool = True,
        overlap: bool = False,
        interval: ScoreInterval | None = None,
        ldr_interval: ScoreInterval | None = None,
        loop_intervals: Mapping[str, ScoreInterval] | None = None,
        spread: bool = False,
        spread_interval: SpreadInterval | None = None,
        spread_ldr_interval: SpreadInterval | None = None,
        pixel_filter: str = "box",
    ):
        output = getattr(net, "output", None)
        if output not in ("map", "patch"):
            raise TypeError(
                f"Scorer needs a model from nriqa.models (output 'map' or 'patch'), got {type(net).__name__}"
            )
        if stride < 1:
            raise ValueError(f"stride must be >= 1, got {stride}")
        if tile < 0:
            raise ValueError(f"tile must be >= 0 (0 = never tile), got {tile}")
        if pixel_filter not in PIXEL_FILTERS:
            raise ValueError(f"pixel_filter must be one of {list(PIXEL_FILTERS)}, got {pixel_filter!r}")
        window = int(getattr(net, "window", 0) or 0) if window is None else int(window)
        if window < 0 or (output != "map" and window):
            raise ValueError(f"window must be >= 0 and is for map models only, got {window} for {type(net).__name__}")
        if device is None:
            device = next(net.parameters()).device
        # batch norm folded into its convolution: the same map to float rounding, 2-20 % faster
        self.net = fold_batchnorm(net).to(device)
        self.device = torch.device(device)
        self.output = output
        self.receptive_field = int(net.receptive_field)
        # the smallest image worth scoring: the local window (a context model's field is much larger)
        self.min_size = int(getattr(net, "min_size", self.receptive_field))
        self.needs_albedo = bool(getattr(net, "albedo", False))
        self.needs_twin = int(getattr(net, "in_channels", 3)) - 3 * self.needs_albedo == 6
        self.align = int(getattr(net, "align", 1))
        self.tile = -(-tile // self.align) * self.align if tile else 0
        self.window = max(window, self.min_size) if window else 0
        self.overlap = bool(overlap)
        self.stride = int(stride)
        self.quantity = "ssim" if output == "map" else "mae"
        self.exact_flat = bool(exact_flat) and output == "map"
        loop_intervals = dict(loop_intervals or {})
        unknown = set(loop_intervals) - set(LOOP_KINDS)
        if unknown:
            raise ValueError(f"loop intervals are for loop kinds {list(LOOP_KINDS)}, got {sorted(unknown)}")
        for given in (interval, ldr_interval, *loop_intervals.values()):
            if given is not None and not isinstance(given, ScoreInterval):
                raise TypeError(f"a score interval must be a ScoreInterval, got {type(given).__name__}")
            if given is not None and self.quantity != "ssim":
                raise ValueError("a score interval is for SSIM map models; the patch model predicts an MAE")
        if ldr_interval is not None and interval is None:
            raise ValueError("ldr_interval refines interval for LDR input; give interval too")
        for given in (spread_interval, spread_ldr_interval):
            if given is not None and not isinstance(given, SpreadInterval):
                raise TypeError(f"a spread interval must be a SpreadInterval, got {type(given).__name__}")
        if (spread_interval is not None or spread_ldr_interval is not None) and interval is None:
            raise ValueError("spread intervals refine interval; give interval too")
        if spread and (self.quantity != "ssim" or self.needs_twin or self.needs_albedo):
            raise ValueError(
                "spread=True (nriqa-predict --spread) is for single-image SSIM map models, no twin or albedo pass"
            )
        self.spread = bool(spread)
        self.spread_interval = spread_interval
        self.spread_ldr_interval = spread_ldr_interval
        self.interval = interval
        self.ldr_interval = ldr_interval
        self.loop_intervals = loop_intervals
        self.pixel_filter = pixel_filter

    @property
    def higher_is_better(self) -> bool:
        """True for an SSIM map (map models), False for an MAE map (the patch model)."""
        return self.quantity == "ssim"

    @classmethod
    def from_pretrained(cls, name: str | None = None, *, dir: str | os.PathLike | None = None, **kwargs) -> Scorer:
        """A scorer with the shipped weights ``name`` (:func:`nriqa.inference.pretrained.load_pretrained`).

        Without a name: the default single-image weights, :data:`nriqa.inference.DEFAULT_WEIGHTS`.
        The card's calibrated ``score_interval`` (and ``score_interval_ldr``, ``score_interval_loop_uniform``,
        ``score_interval_loop_adaptive``, ``score_interval_spread``, ``score_interval_spread_ldr``), if it has them,
        become the scorer's ``interval`` (and ``ldr_interval``, ``loop_intervals``, ``spread_interval``,
        ``spread_ldr_interval``) unless given
        (``interval=None`` turns them all off); the card's
        ``pixel_filter`` (``"box"`` if it has none) becomes the scorer's.
        """
        from nriqa.inference import DEFAULT_WEIGHTS
        from nriqa.inference.pretrained import PretrainedError, load_card, net_from_card

        name = name or DEFAULT_WEIGHTS
        card, pt = load_card(name, dir)
        net = net_from_card(card, pt)
        if "interval" not in kwargs:

            def card_interval(key, kind):
                try:
                    return kind.from_dict(card[key]) if card.get(key) is not None else None
                except ValueError as exc:
                    tool = "nriqa.eval.spread" if kind is SpreadInterval else "nriqa.eval.coverage"
                    raise PretrainedError(
                        f"weights {name!r}: the card's {key}: {exc}; re-fit it (python -m {tool} fit)"
                    ) from None

            for key, arg, kind in (
                ("score_interval", "interval", ScoreInterval),
                ("score_interval_ldr", "ldr_interval", ScoreInterval),
                ("score_interval_spread", "spread_interval", SpreadInterval),
                ("score_interval_spread_ldr", "spread_ldr_interval", SpreadInterval),
            ):
                kwargs.setdefault(arg, card_interval(key, kind))
            loops = {k: card_interval(loop_card_key(k), ScoreInterval) for k in LOOP_KINDS}
            kwargs.setdefault("loop_intervals", {k: v for k, v in loops.items() if v is not None})
        learnt = card.get("pixel_filter", "box")
        if learnt not in PIXEL_FILTERS:
            raise PretrainedError(
                f"weights {name!r}: the card's pixel_filter {learnt!r} is none of {list(PIXEL_FILTERS)}"
            )
        kwargs.setdefault("pixel_filter", learnt)
        return cls(net, **kwargs)

    @classmethod
    def from_checkpoint(cls, path: str | os.PathLike, **kwargs) -> Scorer:
        """A scorer with the network of a training checkpoint (``load_net_from_checkpoint``)."""
        from nriqa.training.checkpoint import load_net_from_checkpoint

        return cls(load_net_from_checkpoint(path), **kwargs)

    def __call__(
        self,
        image: np.ndarray | Tensor,
        *,
        hdr: bool | None = None,
        twin: np.ndarray | Tensor | None = None,
        albedo: np.ndarray | Tensor | None = None,
    ) -> ScoreResult:
        """Score one image or a batch; see the class docstring for shapes and the HDR/LDR rule.

        Args:
            image: the render(s) to score.
            hdr: force linear HDR (tone-mapped) or LDR; ``None`` decides per image.
            twin: for a two-buffer model (``needs_twin``): an independent render of the same image at
                the same spp, in the same layout; it goes through the same HDR/LDR decision as ``image``.
            albedo: for a model with the albedo pass (``needs_albedo``): the scene's albedo pass in
                the same layout, reflectances in [0, 1].

        Returns:
            :class:`ScoreResult` with the map ``(H, W)`` / ``(B, H, W)`` and the mean-pooled score.
        """
        is_numpy = not isinstance(image, Tensor)
        batch, single = _as_batch(image)
        out_device = self.device if is_numpy else batch.device
        b, _, h, w = batch.shape
        if b == 0:
            raise ScorerInputError("empty batch: give at least one image")
        if min(h, w) < self.min_size:
            what = "receptive field" if self.min_size == self.receptive_field else "smallest input"
            raise ScorerInputError(
                f"image of {h}x{w} pixels is smaller than the {self.min_size}x{self.min_size} "
                f"{what} of {type(self.net).__name__}; give at least {self.min_size} pixels a side"
            )
        extra = self._extra_batch(twin, albedo, batch.shape)
        with torch.inference_mode():
            flags = self.detect_hdr(batch, hdr)
            qmap = self._final_map(batch, flags, extra)
            scores = _pool(qmap)
            spread = None
            if self.spread:  # the other seven views, each image's flags with it (views come in blocks of B)
                views = view_scores(lambda v: _pool(self._final_map(v, flags * (len(v) // b))), batch, scores)
                spread = score_spread(views).to(out_device)
        qmap = qmap.to(out_device)
        scores = scores.to(out_device)
        if is_numpy:
            qmap, scores = qmap.cpu().numpy(), scores.cpu().numpy()
            spread = None if spread is None else spread.cpu().numpy()
        low = high = None
        if self.interval is not None:
            plain = np.asarray(scores if is_numpy else scores.cpu().numpy())
            spreads = None if spread is None else np.asarray(spread if is_numpy else spread.cpu().numpy())
            ends = self.interval_ends(plain, flags, spreads)
            if is_numpy:
                low, high = (v.astype(scores.dtype) for v in ends)
            else:
                low, high = (torch.as_tensor(v, dtype=scores.dtype, device=out_device) for v in ends)
        if single:
            if low is not None:
                low, high = float(low[0]), float(high[0])
            one = None if spread is None else float(spread[0])
            return ScoreResult(qmap[0], float(scores[0]), self.quantity, flags[0], low, high, one)
        return ScoreResult(qmap, scores, self.quantity, flags, low, high, spread)

    def _final_map(self, batch: Tensor, flags: list[bool], extra: Tensor | None = None) -> Tensor:
        """The map of ``batch`` as returned: the network's, flat bright windows set to 1 (``exact_flat``)."""
        qmap = self._map(batch, flags, extra)
        if self.exact_flat:
            self._flat_to_one(qmap, batch, flags)
        return qmap

    def interval_ends(
        self, scores: np.ndarray, hdr: list[bool], spread: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Ends of the calibrated interval for pooled ``scores`` of images taken as HDR or not (``hdr``); with
        their ``spread``, the ends of the spread interval for HDR (LDR) images where there is one."""
        values = np.asarray(scores, dtype=np.float64)
        low, high = self.interval(values)
        ldr = ~np.asarray(hdr, dtype=bool)
        if self.ldr_interval is not None:
            low[ldr], high[ldr] = (end[ldr] for end in self.ldr_interval(values))
        if spread is not None:
            for iv, rows in ((self.spread_interval, ~ldr), (self.spread_ldr_interval, ldr)):
                if iv is not None:
                    low[rows], high[rows] = (end[rows] for end in iv(values, np.asarray(spread, np.float64)))
        return low, high

    def _extra_batch(
        self, twin: np.ndarray | Tensor | None, albedo: np.ndarray | Tensor | None, shape: torch.Size
    ) -> Tensor | None:
        """The twin and/or the albedo pass the model takes, stacked on channels as a batch like the
        image's, or ``None``; a refusal names what is wrong."""
        name = type(self.net).__name__
        parts = []
        for what, given, needed, missing, unwanted in (
            (
                "twin",
                twin,
                self.needs_twin,
                "scores an image with its twin: pass twin= (predict.py --twin TWIN)",
                "scores one image; a twin needs a two-buffer model (dual_fast)",
            ),
            (
                "albedo pass",
                albedo,
                self.needs_albedo,
                "scores an image with its scene's albedo pass: pass albedo= (predict.py --albedo ALBEDO)",
                "takes no albedo pass; leave it out, or choose a model trained with one (unet_fast_albedo)",
            ),
        ):
            if given is None:
                if needed:
                    raise ScorerInputError(f"{name} {missing}")
                continue
            if not needed:
                raise ScorerInputError(f"{name} {unwanted}")
            batch, _ = _as_batch(given)
            if batch.shape != shape:
                raise ScorerInputError(
                    f"the {what} is {tuple(batch.shape[-2:])} but the image is {tuple(shape[-2:])} "
                    "(height, width); give one of the same size"
                )
            parts.append(batch)
        return torch.cat(parts, dim=1) if parts else None

    @staticmethod
    def detect_hdr(batch: Tensor, hdr: bool | None = None) -> list[bool]:
        """Per image of a ``(B, 3, H, W)`` batch: treat it as linear HDR? (``hdr`` forces the answer.)

        Automatic rule: HDR if any value is above 1 (``+inf`` included, NaN not). Integer inputs
        arrive here already scaled to [0, 1], so they are LDR.
        """
        if hdr is not None:
            return [bool(hdr)] * batch.shape[0]
        return [bool((img > 1).any()) for img in batch]

    @staticmethod
    def prepare(batch: Tensor, flags: list[bool]) -> Tensor:
        """Sanitise and tone map a float ``(B, 3, h, w)`` batch (or a tile of it) into network input.

        Pixel-wise, so it can be applied per tile. Returns float32 ``(B, 3, h, w)`` in [0, 1]:
        :func:`nriqa.core.tonemap.tonemap` for the images flagged HDR, NaN/negative -> 0 and
        ``+inf``/above 1 -> 1 for the others.
        """
        out = torch.empty(batch.shape, dtype=torch.float32, device=batch.device)
        for i, (img, is_hdr) in enumerate(zip(batch, flags)):
            img = img if img.dtype == torch.float64 else img.float()
            if is_hdr:
                out[i] = tonemap(img)
            else:
                out[i] = torch.nan_to_num(img, nan=0.0, posinf=1.0, neginf=0.0).clamp(0.0, 1.0)
        return out

    def _input(self, batch: Tensor, flags: list[bool], extra: Tensor | None) -> Tensor:
        """Network input on ``self.device``: the prepared image, with the prepared twin and the albedo
        pass (:meth:`_extra_batch`'s channels) stacked on its channels."""
        parts = [self.prepare(batch, flags)]
        if extra is not None and self.needs_twin:
            parts.append(self.prepare(extra[:, :3], flags))
        if extra is not None and self.needs_albedo:
            parts.append(torch.nan_to_num(extra[:, -3:].float(), nan=0.0, posinf=1.0, neginf=0.0).clamp(0.0, 1.0))
        return torch.cat(parts, dim=1).to(self.device) if len(parts) > 1 else parts[0].to(self.device)

    def _map(self, batch: Tensor, flags: list[bool], extra: Tensor | None = None) -> Tensor:
        """Raw ``(B, 3, H, W)`` batch (and twins, albedo passes) -> ``(B, H, W)`` predicted map on ``self.device``."""
        if self.output == "patch":
            return self._patch_map(self.prepare(batch, flags).to(self.device))
        h, w = batch.shape[-2:]
        if self.window and (h > self.window or w > self.window):
            return self._windowed_map(batch, flags, extra)
        if not self.tile or (h <= self.tile and w <= self.tile):
            return self.net(self._input(batch, flags, extra))[:, 0].clamp(0.0, 1.0)
        return self._tiled_map(batch, flags, extra)

    def _flat_to_one(self, qmap: Tensor, batch: Tensor, flags: list[bool]) -> None:
        """Set ``qmap`` to 1 in place where the image's whole SSIM window is one bright colour.

        Image by image and tile by tile (``tile``, grown by the window's radius, which is all a pixel's
        window reaches), so memory follows the tile as for the network.
        """
        h, w = batch.shape[-2:]
        for rows, cols, (ry, rx), (cy, cx) in _halo_tiles(h, w, self.tile or max(h, w), WINDOW // 2):
            for i, flag in enumerate(flags):
                piece = batch[i : i + 1, :, ry, rx]
                if not may_be_flat(self.prepare(piece[..., ::FLAT_ROWS, :], [flag])):
                    continue
                flat = flat_windows(self.prepare(piece, [flag]))[0, cy, cx]
                qmap[i, rows, cols].masked_fill_(flat.to(qmap.device), 1.0)

    def _tiled_map(self, batch: Tensor, flags: list[bool], extra: Tensor | None = None) -> Tensor:
        b, _, h, w = batch.shape
        t, a = self.tile, self.align
        half = -(-self.receptive_field // 2)
        halo = -(-half // a) * a
        out = torch.empty(b, h, w, dtype=torch.float32, device=self.device)
        for rows, cols, (ry, rx), (cy, cx) in _halo_tiles(h, w, t, halo):
            window = (slice(None), slice(None), ry, rx)
            tile = self._input(batch[window], flags, None if extra is None else extra[window])
            out[:, rows, cols] = self.net(tile)[:, 0, cy, cx]
        return out.clamp_(0.0, 1.0)

    def _windowed_map(self, batch: Tensor, flags: list[bool], extra: Tensor | None = None) -> Tensor:
        """Independent ``window``-side pieces, batched; overlaps averaged (``overlap``: tent-weighted).

        Side by side, only the last piece in each direction (moved in to touch the border) overlaps.
        """
        b, _, h, w = batch.shape
        wh, ww = min(self.window, h), min(self.window, w)
        if self.overlap:
            ys, xs = _window_starts(h, wh, max(1, wh // 2)), _window_starts(w, ww, max(1, ww // 2))
            weight = _tent(wh, self.device)[:, None] * _tent(ww, self.device)[None, :]
        else:
            ys, xs = _window_starts(h, wh, wh), _window_starts(w, ww, ww)
            weight = torch.ones(wh, ww, dtype=torch.float32, device=self.device)
        total = torch.zeros(b, h, w, dtype=torch.float32, device=self.device)
        count = torch.zeros(h, w, dtype=torch.float32, device=self.device)
        chunk = max(1, ((self.tile or 512) ** 2) // (wh * ww))
        for y0 in ys:
            rows = (slice(None), slice(None), slice(y0, y0 + wh))
            strip = self._input(batch[rows], flags, None if extra is None else extra[rows])  # (B, C, wh, W)
            pieces = torch.stack([strip[..., x0 : x0 + ww] for x0 in xs], dim=1).flatten(0, 1)  # (B*nx, C, wh, ww)
            pred = torch.cat([self.net(pieces[i : i + chunk])[:, 0] for i in range(0, pieces.shape[0], chunk)])
            pred = pred.view(b, len(xs), wh, ww)
            for k, x0 in enumerate(xs):
                total[:, y0 : y0 + wh, x0 : x0 + ww] += pred[:, k] * weight
                count[y0 : y0 + wh, x0 : x0 + ww] += weight
        return (total / count).clamp_(0.0, 1.0)

    def _patch_map(self, x: Tensor) -> Tensor:
        """Sliding-window map of the patch model: each window's score averaged over its pixels."""
        b, _, h, w = x.shape
        p = self.receptive_field
        ys, xs = _window_starts(h, p, self.stride), _window_starts(w, p, self.stride)
        xs_t = torch.tensor(xs, device=x.device)
        # Windows form a product grid, so the per-pixel window count is separable.
        count = _coverage(ys, p, h, x.device)[:, None] * _coverage(xs, p, w, x.device)[None, :]
        total = torch.zeros(b, h, w, dtype=torch.float64, device=x.device)
        chunk = max(1, (self.tile or 512) * 4)
        for y0 in ys:
            strip = x[:, :, y0 : y0 + p, :]  # (B, 3, p, W)
            windows = torch.stack([strip[..., x0 : x0 + p] for x0 in xs], dim=1).flatten(0, 1)  # (B*nx, 3, p, p)
            scores = torch.cat([self.net(windows[i : i + chunk])[:, 0] for i in range(0, windows.shape[0], chunk)])
            scores = scores.view(b, len(xs)).double()
            # Spread each window's score over its columns with a difference array, then cumsum.
            diff = torch.zeros(b, w + 1, dtype=torch.float64, device=x.device)
            diff.index_add_(1, xs_t, scores)
            diff.index_add_(1, xs_t + p, -scores)
            total[:, y0 : y0 + p, :] += diff[:, :w].cumsum(dim=1)[:, None, :]
        return (total / count).float()


def _pool(qmap: Tensor) -> Tensor:
    """``(B,)`` mean of each map of ``(B, H, W)``, summed in float64."""
    return qmap.mean(dim=(-2, -1), dtype=torch.float64).float()


def _halo_tiles(h: int, w: int, tile: int, halo: int):
    """Square ``tile``-side output tiles of an ``h x w`` image, each read from the tile grown by ``halo``.

    Yields ``(rows, cols, (read_rows, read_cols), (crop_rows, crop_cols))``: the output slices, the
    slices of the image to read, and where the output tile lies in what was read.
    """
    for y0 in range(0, h, tile):
        y1, iy0 = min(y0 + tile, h), max(0, y0 - halo)
        for x0 in range(0, w, tile):
            x1, ix0 = min(x0 + tile, w), max(0, x0 - halo)
            read = (slice(iy0, min(h, y1 + halo)), slice(ix0, min(w, x1 + halo)))
            yield slice(y0, y1), slice(x0, x1), read, (slice(y0 - iy0, y1 - iy0), slice(x0 - ix0, x1 - ix0))


def _tent(n: int, device: torch.device) -> Tensor:
    """``(n,)`` tent weights ``min(i + 1/2, n - i - 1/2) / (n / 2)``: in (0, 1], two at half-``n`` steps sum to 1."""
    i = torch.arange(n, dtype=torch.float32, device=device) + 0.5
    return torch.minimum(i, n - i) / (n / 2)


def _window_starts(n: int, p: int, stride: int) -> list[int]:
    """Window starts ``0, stride, ...`` plus ``n - p`` so the last window touches the border."""
    starts = list(range(0, n - p + 1, stride))
    if starts[-1] != n - p:
        starts.append(n - p)
    return starts


def _coverage(starts: list[int], p: int, n: int, device) -> Tensor:
    c = torch.zeros(n + 1, dtype=torch.float64, device=device)
    s = torch.tensor(starts, device=device)
    c.index_add_(0, s, torch.ones(len(starts), dtype=torch.float64, device=device))
    c.index_add_(0, s + p, -torch.ones(len(starts), dtype=torch.float64, device=device))
    return c[:n].cumsum(0)


def _as_batch(image: np.ndarray | Tensor) -> tuple[Tensor, bool]:
    """Any accepted layout -> float ``(B, 3, H, W)`` tensor (not yet sanitised) and whether it was one image."""
    dtype = image.dtype if isinstance(image, (np.ndarray, Tensor)) else None
    if isinstance(image, Tensor):
        t = image.detach()
        channels_last = False
    elif isinstance(image, np.ndarray):
        if image.dtype == np.uint16:  # torch has no general uint16 support
            image = image.astype(np.int32)
        try:
            t = torch.from_numpy(np.ascontiguousarray(image))
        except TypeError:
            raise ScorerInputError(
                f"unsupported numpy dtype {image.dtype}; give float or uint8/uint16 images"
            ) from None
        channels_last = True
    else:
        raise ScorerInputError(f"expected a numpy array or torch tensor, got {type(image).__name__}")
    if t.dtype == torch.bool or t.is_complex():
        raise ScorerInputError(f"unsupported dtype {dtype}; give float or uint8/uint16 images")
    if t.ndim == 2:
        t, single = t[None, None], True
    elif t.ndim == 3:
        t, single = (t.permute(2, 0, 1) if channels_last else t)[None], True
    elif t.ndim == 4:
        t, single = (t.permute(0, 3, 1, 2) if channels_last else t), False
    else:
        raise ScorerInputError(f"expected an image (H,W[,C]) or a batch, got shape {tuple(image.shape)}")
    c = t.shape[1]
    layout = "(H, W, C)" if channels_last else "(C, H, W)"
    if c in (1, 2):  # gray, gray + alpha
        t = t[:, :1].expand(-1, 3, -1, -1)
    elif c == 4:
        t = t[:, :3]
    elif c != 3:
        raise ScorerInputError(f"expected 1, 3 or 4 channels in layout {layout}, got shape {tuple(image.shape)}")
    if not t.is_floating_point():
        scale = {np.dtype(np.uint8): 255.0, torch.uint8: 255.0, np.dtype(np.uint16): 65535.0}.get(dtype)
        if scale is None:
            raise ScorerInputError(f"integer images must be uint8 or uint16, got {dtype}; convert to float")
        t = t.float() / scale
    return t, single


def device_problem(name: str) -> str | None:
    """Why a scorer cannot run on the torch device ``name`` here (one line, for ``--device`` options), or None."""
    try:
        device = torch.device(name)
    except (RuntimeError, ValueError):
        return f"--device {name!r} is not a torch device; use cpu or cuda"
    if device.type == "cpu":
        return None
    try:
        torch.zeros(1, device=device)
    except (RuntimeError, AssertionError, ValueError) as exc:  # no such device, or torch built without it
        why = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        return f"--device {name}: not usable here ({why}); use --device cpu"
    return None
