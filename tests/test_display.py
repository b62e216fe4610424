"""Display transforms: exposure + sRGB / gamma 2.2 with clipping, 8-bit quantisation, the tone map."""

import math

import pytest
import torch
from kornia.color import rgb_to_linear_rgb

from nriqa.core.display import CURVES, Display, DisplayMix, apply_display, display_pair, key_exposure, quantise
from nriqa.core.tonemap import tonemap


def _hdr(seed=0, shape=(2, 3, 16, 16), scale=4.0):
    return torch.rand(shape, generator=torch.Generator().manual_seed(seed)) * scale


def test_tonemap_curve_is_the_package_tone_map():
    x = _hdr()
    assert torch.equal(apply_display(x, Display("tonemap")), tonemap(x))


def test_srgb_inverts_to_the_clipped_exposed_linear_image():
    x = _hdr()
    scale = key_exposure(x)
    out = apply_display(x, Display("srgb", stops=1.0), scale)
    expected = (x * scale * 2.0).clamp(0, 1)
    torch.testing.assert_close(rgb_to_linear_rgb(out), expected, atol=1e-5, rtol=1e-4)


def test_gamma22_and_clipping_of_highlights():
    x = torch.full((1, 3, 4, 4), 0.25)
    x[..., 0, 0] = 1e6  # a firefly is clipped white, not Inf/NaN
    out = apply_display(x, Display("gamma22"), scale=1.0)
    assert out[..., 0, 0].eq(1.0).all()
    torch.testing.assert_close(out[..., 1, 1], torch.full((1, 3), 0.25 ** (1 / 2.2)))


def test_key_exposure_maps_log_average_to_middle_grey():
    x = torch.full((1, 3, 8, 8), 3.0)
    torch.testing.assert_close(key_exposure(x).flatten(), torch.tensor([0.18 / 3.0]), rtol=1e-4, atol=0)
    # a dimmer copy gets a proportionally larger exposure: the displayed image is the same
    for curve in ("srgb", "gamma22"):
        a = apply_display(x, Display(curve), key_exposure(x))
        b = apply_display(x / 64, Display(curve), key_exposure(x / 64))
        torch.testing.assert_close(a, b, atol=1e-4, rtol=0)


def test_black_reference_gets_unit_exposure_and_finite_output():
    x = torch.zeros(1, 3, 8, 8)
    assert key_exposure(x).item() == 1.0
    for curve in CURVES:
        out = apply_display(x, Display(curve, bits=8), key_exposure(x))
        assert torch.isfinite(out).all() and out.max() == 0


def test_bad_pixels_never_give_nan():
    x = _hdr()
    x[0, :, 0, 0] = float("nan")
    x[0, 0, 1, 1] = float("inf")
    x[1, :, 2, 2] = -5.0
    x[1, 1, 3, 3] = 1e30
    for curve in CURVES:
        out = apply_display(x, Display(curve, stops=3.0), key_exposure(x))
        assert torch.isfinite(out).all() and out.min() >= 0 and out.max() <= 1
        assert out[0, :, 0, 0].eq(0).all()  # NaN -> black
        assert out[0, :, 1, 1].eq(1).all()  # a pixel with +Inf is white, as in the tone map


def test_quantise_gives_8_bit_levels():
    x = torch.linspace(0, 1, 1001)
    q = quantise(x, 8)
    assert torch.allclose(q * 255, torch.round(q * 255), atol=1e-5)
    assert (q - x).abs().max() <= 0.5 / 255 + 1e-7
    assert len(torch.unique(q)) == 256


def test_pair_is_transformed_identically():
    noisy, ref = _hdr(1), _hdr(2)
    for display in (Display("tonemap"), Display("srgb", -1.5, 8), Display("gamma22", 2.0)):
        a, b = display_pair(noisy, ref, display)
        scale = key_exposure(ref) if display.curve != "tonemap" else 1.0
        assert torch.equal(a, apply_display(noisy, display, scale))
        assert torch.equal(b, apply_display(ref, display, scale))
        # the same image as both members gives two identical displayed images
        c, d = display_pair(ref, ref, display)
        assert torch.equal(c, d)


def test_mix_is_deterministic_and_covers_every_curve():
    mix = DisplayMix()
    draws = [mix.sample(torch.Generator().manual_seed(s)) for s in range(400)]
    again = [mix.sample(torch.Generator().manual_seed(s)) for s in range(400)]
    assert draws == again
    counts = {c: sum(d.curve == c for d in draws) for c in CURVES}
    assert counts["tonemap"] > 150 and counts["srgb"] > 60 and counts["gamma22"] > 60
    assert all(d.stops == 0 for d in draws if d.curve == "tonemap")
    assert max(abs(d.stops) for d in draws) <= mix.stops and max(abs(d.stops) for d in draws) > 1.5
    assert 150 < sum(d.bits == 8 for d in draws) < 250


def test_only_tonemap_mix_draws_the_tone_map():
    mix = DisplayMix(tonemap=1.0, srgb=0.0, gamma22=0.0, quantise_p=0.0)
    g = torch.Generator().manual_seed(0)
    assert {mix.sample(g) for _ in range(50)} == {Display("tonemap")}


@pytest.mark.parametrize(
    "kwargs",
    [dict(curve="log"), dict(bits=0), dict(bits=32), dict(stops=math.inf)],
)
def test_bad_display_is_refused(kwargs):
    with pytest.raises(ValueError):
        Display(**kwargs)


@pytest.mark.parametrize("kwargs", [dict(tonemap=-1.0), dict(tonemap=0, srgb=0, gamma22=0), dict(quantise_p=2)])
def test_bad_mix_is_refused(kwargs):
    with pytest.raises(ValueError):
        DisplayMix(**kwargs)


@pytest.mark.parametrize(
    "spec, display",
    [
        ("tonemap", Display("tonemap")),
        ("tonemap:8", Display("tonemap", bits=8)),
        ("srgb", Display("srgb")),
        ("SRGB+2", Display("srgb", 2.0)),
        ("gamma22-1.5:8", Display("gamma22", -1.5, 8)),
    ],
)
def test_display_spec_parses_and_prints_back(spec, display):
    assert Display.parse(spec) == display
    assert Display.parse(str(display)) == display


@pytest.mark.parametrize(
    "spec, message",
    [
        ("log", "CURVE[+-STOPS][:BITS]"),
        ("srgb+", "CURVE[+-STOPS][:BITS]"),
        ("srgb:0", "bits must be in 1..16"),
        ("tonemap+1", "no exposure"),
        ("srgb 2", "CURVE[+-STOPS][:BITS]"),
    ],
)
def test_bad_display_spec_is_one_line(spec, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("+", r"\+")) as exc:
        Display.parse(spec)
    assert "\n" not in str(exc.value)
