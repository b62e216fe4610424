import numpy as np
import pytest
import torch

from nriqa.losses import JointLoss, charbonnier, create_loss, list_losses, pearson

NAMES = ["l1", "l2", "charbonnier", "pcc", "joint"]


def test_registry():
    assert list_losses() == sorted(NAMES)
    for name in NAMES:
        assert isinstance(create_loss(name), torch.nn.Module)
    assert create_loss("joint", delta=0.5).delta == 0.5
    with pytest.raises(ValueError, match="charbonnier, joint, l1, l2, pcc"):
        create_loss("huber")


def _cases():
    g = torch.Generator().manual_seed(0)
    r = torch.rand(4, 1, 8, 8, generator=g)
    s = torch.rand(4, 1, 8, 8, generator=g)
    c = torch.full_like(r, 0.3)
    return {
        "random": (r, s),
        "constant_pred": (c, s),
        "dead_relu": (torch.zeros_like(r), s),
        "constant_target": (r, c),
        "both_constant": (c, torch.full_like(r, 0.7)),
        "both_equal_constant": (c, c.clone()),
        "zero": (torch.zeros_like(r), torch.zeros_like(r)),
        "batch_of_one": (r[:1], s[:1]),
        "single_element": (r[:1, :, :1, :1], s[:1, :, :1, :1]),
        "huge": (r * 1e6, s * 1e6),
        "huge_constant": (torch.full_like(r, 1e6), s * 1e6),
        "huge_gap": (torch.full_like(r, 1e6), -s * 1e6),
    }


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("case", list(_cases()))
def test_finite_loss_and_grads(name, case):
    pred, target = _cases()[case]
    pred = pred.clone().requires_grad_(True)
    target = target.clone().requires_grad_(True)
    loss = create_loss(name)(pred, target)
    assert loss.ndim == 0 and torch.isfinite(loss)
    loss.backward()
    assert torch.isfinite(pred.grad).all() and torch.isfinite(target.grad).all()


def test_simple_values():
    p, t = torch.tensor([0.0, 1.0, 3.0]), torch.tensor([1.0, 1.0, 1.0])
    torch.testing.assert_close(create_loss("l1")(p, t), torch.tensor(1.0))
    torch.testing.assert_close(create_loss("l2")(p, t), torch.tensor(5.0 / 3))
    expected = np.mean(np.sqrt(np.array([1.0, 0.0, 4.0]) + 1e-6))
    torch.testing.assert_close(create_loss("charbonnier")(p, t), torch.tensor(expected, dtype=torch.float32))


def test_charbonnier_of_equal_is_eps():
    y = torch.rand(3, 5)
    assert charbonnier(y, y).item() == pytest.approx(1e-3, rel=1e-6)
    assert create_loss("charbonnier", eps=0.1)(y, y).item() == pytest.approx(0.1, rel=1e-6)
    assert charbonnier(torch.zeros(1), torch.full((1,), 1e30)).item() == pytest.approx(1e30, rel=1e-6)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_pcc_matches_numpy(dtype):
    g = torch.Generator().manual_seed(1)
    for scale in (1e-2, 1.0, 1e6):
        x = torch.rand(16, 1, 4, 4, generator=g, dtype=dtype) * scale
        y = 0.5 * x + torch.rand(16, 1, 4, 4, generator=g, dtype=dtype) * scale
        expected = np.corrcoef(x.double().flatten().numpy(), y.double().flatten().numpy())[0, 1]
        assert pearson(x, y).item() == pytest.approx(expected, abs=1e-6)
        assert create_loss("pcc")(x, y).item() == pytest.approx(1 - abs(expected), abs=1e-6)
        assert create_loss("pcc")(x, -y).item() == pytest.approx(1 - abs(expected), abs=1e-6)


def test_pcc_undefined_is_zero():
    y = torch.rand(10)
    assert pearson(torch.zeros(10), y).item() == 0.0
    assert pearson(y, torch.full((10,), 0.4)).item() == 0.0
    assert create_loss("pcc")(torch.zeros(10), torch.zeros(10)).item() == 1.0


def test_joint_is_sum_of_terms():
    g = torch.Generator().manual_seed(2)
    p, t = torch.rand(32, generator=g), torch.rand(32, generator=g)
    for delta in (0.0, 1.0, 2.5):
        expected = delta * create_loss("pcc")(p, t) + charbonnier(p, t)
        torch.testing.assert_close(JointLoss(delta=delta)(p, t), expected)
    assert JointLoss()(t, t).item() == pytest.approx(1e-3, abs=1e-6)


def test_joint_mean_term_compares_each_examples_mean():
    g = torch.Generator().manual_seed(3)
    t = torch.rand(4, 1, 8, 8, generator=g)
    shuffled = t.flatten(1)[:, torch.randperm(64, generator=g)].reshape(t.shape)  # same means, other pixels
    plain, with_mean = JointLoss(signed=True), JointLoss(signed=True, mean_weight=2.0)
    torch.testing.assert_close(
        with_mean(shuffled, t), plain(shuffled, t) + 2.0 * charbonnier(t.mean((1, 2, 3)), t.mean((1, 2, 3)))
    )
    offset = t + torch.tensor([0.1, -0.1, 0.0, 0.0]).view(4, 1, 1, 1)  # two examples' means off by 0.1
    extra = with_mean(offset, t) - plain(offset, t)
    expected = 2.0 * torch.sqrt(torch.tensor([0.01, 0.01, 0.0, 0.0]) + 1e-6).mean()
    torch.testing.assert_close(extra, expected)
    pred = offset.clone().requires_grad_(True)
    (with_mean(pred, t) - plain(pred, t)).backward()
    assert pred.grad[0].sum() > 0 > pred.grad[1].sum()  # pushes each mean back towards its target's
    with pytest.raises(ValueError, match="mean_weight"):
        JointLoss(mean_weight=-1.0)


@pytest.mark.parametrize("name", NAMES)
def test_shape_mismatch_and_empty(name):
    loss = create_loss(name)
    with pytest.raises(ValueError, match="same shape"):
        loss(torch.rand(4), torch.rand(4, 1))
    with pytest.raises(ValueError, match="empty"):
        loss(torch.rand(0), torch.rand(0))
    with pytest.raises(TypeError):
        loss(torch.zeros(3, dtype=torch.long), torch.zeros(3, dtype=torch.long))


def test_bad_constructor_args():
    with pytest.raises(ValueError):
        create_loss("charbonnier", eps=0)
    with pytest.raises(ValueError):
        create_loss("joint", delta=-1)
