import numpy as np
import pytest
import scipy.stats
import torch

from nriqa.correlation import kendall_tau, pcc, srocc

FUNCS = {
    "pcc": (pcc, scipy.stats.pearsonr),
    "srocc": (srocc, scipy.stats.spearmanr),
    "kendall_tau": (kendall_tau, scipy.stats.kendalltau),
}


@pytest.mark.parametrize("name", list(FUNCS))
def test_matches_scipy(name):
    ours, ref = FUNCS[name]
    g = torch.Generator().manual_seed(0)
    a = torch.rand(40, generator=g)
    b = a + 0.5 * torch.rand(40, generator=g)
    b[::7] = b[0]  # ties
    r = ours(a, b)
    assert isinstance(r, float)
    assert r == pytest.approx(ref(a.numpy(), b.numpy())[0], abs=1e-5)
    assert ours(a.numpy(), b.tolist()) == pytest.approx(r, abs=1e-6)  # array-likes too


@pytest.mark.parametrize("name", list(FUNCS))
def test_perfect_and_reversed(name):
    f = FUNCS[name][0]
    a = torch.arange(10.0)
    assert f(a, a**3 if name != "pcc" else 2 * a + 1) == pytest.approx(1.0)
    assert f(a, -a) == pytest.approx(-1.0)


@pytest.mark.parametrize("name", list(FUNCS))
def test_constant_input_is_zero(name):
    f = FUNCS[name][0]
    a = torch.rand(10)
    assert f(torch.full((10,), 0.5), a) == 0.0
    assert f(a, torch.zeros(10)) == 0.0
    assert f(torch.ones(10), torch.ones(10)) == 0.0


@pytest.mark.parametrize("name", list(FUNCS))
def test_errors(name):
    f = FUNCS[name][0]
    with pytest.raises(ValueError, match="same length"):
        f(torch.rand(5), torch.rand(6))
    with pytest.raises(ValueError, match="1-D"):
        f(torch.rand(2, 5), torch.rand(2, 5))
    with pytest.raises(ValueError, match="at least 2"):
        f(torch.rand(1), torch.rand(1))
    with pytest.raises(ValueError, match="NaN"):
        f(torch.tensor([1.0, float("nan"), 2.0]), torch.rand(3))
    with pytest.raises(TypeError):
        f(["a", "b"], [1.0, 2.0])


def test_grad_tensors_accepted():
    a = torch.rand(8, requires_grad=True)
    assert np.isfinite(pcc(a, torch.rand(8)))
