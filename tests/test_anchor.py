"""Anchored fine-tuning: patches of named families learn the starting network's map, the others their target."""

from __future__ import annotations

import pytest
import torch
from conftest import make_dataset
from test_batched_patches import make_dm
from test_train import compose_cfg

from nriqa.data.anchors import Anchors
from nriqa.losses import create_loss
from nriqa.training.fit import train
from nriqa.training.module import NRIQAModule


def test_patches_of_anchored_families_carry_their_flag_and_the_same_draws(synthetic_dataset):
    plain = make_dm(synthetic_dataset).train_set
    anchored = make_dm(synthetic_dataset, anchor_scenes=["alpha"]).train_set
    scenes = {plain.draw(k).pair.record.scene for k in range(16)}
    assert scenes == {"alpha", "gamma"}, "beta is the validation family"
    items, before = anchored.__getitems__(list(range(16))), plain.__getitems__(list(range(16)))
    for k, ((x, y, flag), (x0, y0)) in enumerate(zip(items, before)):
        assert torch.equal(x, x0) and torch.equal(y, y0), "anchoring changes no draw and no target"
        assert bool(flag) == (plain.draw(k).pair.record.scene == "alpha")
    assert len(plain[0]) == 2, "without anchor_scenes the items stay (input, target)"


@pytest.mark.parametrize(
    ("scenes", "message"),
    [(["delta"], "delta not among the training families"), (["alpha", "gamma"], "names every training family")],
)
def test_anchor_scenes_must_be_some_of_the_training_families(synthetic_dataset, scenes, message):
    with pytest.raises(ValueError, match=message) as info:
        make_dm(synthetic_dataset, anchor_scenes=scenes)
    assert "\n" not in str(info.value)


@pytest.fixture(scope="module")
def second_dataset(tmp_path_factory):
    """Another dataset of the same families (another render of them, as data_gen's zoom crops are)."""
    return make_dataset(tmp_path_factory.mktemp("second"))


def test_patches_of_an_anchored_dataset_root_carry_their_flag_whatever_their_family(synthetic_dataset, second_dataset):
    roots = [str(synthetic_dataset), str(second_dataset)]
    dm = make_dm(roots, anchor_data=[str(second_dataset) + "/"])  # a trailing slash names the same root
    ds = dm.train_set
    flags = [bool(item[2]) for item in ds.__getitems__(list(range(32)))]
    under = [ds.draw(k).pair.record.path.startswith(str(second_dataset)) for k in range(32)]
    assert flags == under and 0 < sum(flags) < 32
    assert {ds.draw(k).pair.record.scene for k in range(32) if flags[k]} == {"alpha", "gamma"}
    assert dm.anchors.describe() == {"anchor_scenes": [], "anchor_data": [str(second_dataset) + "/"]}
    # families and roots together: either makes an image anchored
    both = Anchors(frozenset({"alpha"}), (str(second_dataset),))
    assert [both(p.record) for p in dm.train_pairs] == [
        p.record.scene == "alpha" or p.record.path.startswith(str(second_dataset)) for p in dm.train_pairs
    ]


def test_anchor_data_must_be_one_of_the_roots_and_leave_something_to_learn(synthetic_dataset, second_dataset, tmp_path):
    roots = [str(synthetic_dataset), str(second_dataset)]
    with pytest.raises(ValueError, match="holds none of the training images") as info:
        make_dm(roots, anchor_data=[str(tmp_path)])
    assert "\n" not in str(info.value)
    with pytest.raises(ValueError, match="every training image is anchored") as info:
        make_dm(roots, anchor_data=roots)
    assert "\n" not in str(info.value)
    with pytest.raises(ValueError, match="every training image is anchored"):
        make_dm(roots, anchor_data=[roots[0]], anchor_scenes=["alpha", "gamma"])


def _module() -> NRIQAModule:
    torch.manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Conv2d(3, 1, 3, padding=1), torch.nn.Sigmoid())
    return NRIQAModule(net, create_loss("l2"), optimizer=lambda params: torch.optim.SGD(params, lr=0.1))


def test_anchored_items_learn_the_teachers_map_and_the_others_their_target():
    module = _module()
    x, y = torch.rand(4, 3, 8, 8), torch.rand(4, 1, 8, 8)
    with pytest.raises(RuntimeError, match="need a teacher"):
        module.anchored_target(x, y, torch.tensor([True, False, False, False]))
    module.set_teacher(module.net)
    with torch.no_grad():
        start = module.net(x)
        module.net[0].bias += 1.0  # the student moves; the teacher is a frozen copy
    mixed = module.anchored_target(x, y, torch.tensor([True, False, True, False]))
    assert torch.allclose(mixed[[0, 2]], start[[0, 2]]) and torch.equal(mixed[[1, 3]], y[[1, 3]])
    assert all(not p.requires_grad for p in module._teacher[0].parameters())
    assert not any(k.startswith("_teacher") for k in module.state_dict()), "the teacher is never saved"
    module.net[0].bias.data -= 1.0  # student back at the start: an all-anchored batch has nothing to learn
    loss = {flag: float(module._step((x, y, torch.full((4,), flag)), "train").detach()) for flag in (True, False)}
    assert loss[True] == pytest.approx(0.0, abs=1e-12) and loss[False] > 0.01


def test_training_with_anchor_scenes_needs_a_start_and_saves_no_teacher(tmp_path, synthetic_dataset):
    common = ("experiment=fcnn_fast", "debug=fdr", "data.val_scene=null", "data.anchor_scenes=[alpha]")
    with pytest.raises(ValueError, match="needs init_from"):
        train(compose_cfg(tmp_path / "a", synthetic_dataset, *common))
    _, objects = train(compose_cfg(tmp_path / "b", synthetic_dataset, *common, "init_from=fcnn_fast"))
    model = objects["model"]
    assert model.hparams["anchor_scenes"] == ["alpha"] and model._teacher
    assert set(model.state_dict()) == {f"net.{k}" for k in model.net.state_dict()}


def test_hard_sampling_leaves_anchored_images_their_uniform_share(tmp_path, synthetic_dataset):
    """Anchored images learn the start's own map, so they carry no error for hard sampling: each keeps its uniform
    share 1 / N of the draws, whatever the mix, and hard sampling shares out the rest among the learning images."""
    common = ("experiment=fcnn_fast", "debug=fdr", "data.val_scene=null", "init_from=fcnn_fast")
    args = (*common, "data.anchor_scenes=[alpha]", "hard_sampling.mix=0.5")
    _, objects = train(compose_cfg(tmp_path / "a", synthetic_dataset, *args))
    pairs, cdf = objects["datamodule"].train_pairs, objects["datamodule"].train_set.cdf
    weights = torch.diff(cdf, prepend=torch.zeros(1, dtype=cdf.dtype))
    anchored = torch.tensor([p.record.scene == "alpha" for p in pairs])
    n_a = int(anchored.sum())
    assert 0 < n_a < len(pairs)
    torch.testing.assert_close(weights[anchored], torch.full((n_a,), 1 / len(pairs), dtype=cdf.dtype))
    learning = weights[~anchored]
    assert float(learning.sum()) == pytest.approx(1.0 - n_a / len(pairs))
    assert float(learning.max()) > float(learning.min())  # drawn by error among the learning images
    summary = objects["model"].hparams["hard_sampling"]
    assert summary["images"] == len(pairs) - n_a and summary["anchored_share"] == pytest.approx(n_a / len(pairs))
