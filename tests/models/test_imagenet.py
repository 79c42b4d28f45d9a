"""ImageNet initialisation: torchvision's vgg16_bn / vgg16 state-dict files load into `VGGEncoder`.

The files are written here in torchvision's layout (``torchvision.models.vgg.make_layers`` rebuilt: torchvision is
not a dependency): the encoder then computes torchvision's features, stage by stage."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from torch import nn

from stamlane.cli import main
from stamlane.models import VGGEncoder
from stamlane.models.encoder import IMAGENET_MEAN, IMAGENET_STD
from stamlane.models.imagenet import ImageNetWeightsError, torchvision_conv_indices
from stamlane.training.module import StamLaneModule
from tests.training.tiny_runs import tiny_args

CFG_D = [64, 64, "M", 128, 128, "M", 256, 256, 256, "M", 512, 512, 512, "M", 512, 512, 512, "M"]
"""torchvision's ``cfgs["D"]`` (VGG16)."""


def torchvision_features(batch_norm: bool) -> nn.Sequential:
    """torchvision's ``make_layers(cfgs["D"], batch_norm)``: conv (with bias), [batch norm,] ReLU; max-pools."""
    layers: list[nn.Module] = []
    channels = 3
    for v in CFG_D:
        if v == "M":
            layers.append(nn.MaxPool2d(kernel_size=2, stride=2))
            continue
        conv = nn.Conv2d(channels, int(v), kernel_size=3, padding=1)
        layers += [conv, nn.BatchNorm2d(int(v)), nn.ReLU(inplace=True)] if batch_norm else [conv, nn.ReLU(inplace=True)]
        channels = int(v)
    return nn.Sequential(*layers)


def _write(path: Path, batch_norm: bool, seed: int = 0) -> nn.Sequential:
    """A torchvision-layout file of random weights (random batch-norm statistics too); returns its network."""
    torch.manual_seed(seed)
    features = torchvision_features(batch_norm).eval()
    with torch.no_grad():
        for module in features:
            if isinstance(module, nn.Conv2d):
                module.bias.normal_(0, 0.1)
            if isinstance(module, nn.BatchNorm2d):
                module.weight.uniform_(0.5, 1.5)
                module.bias.normal_(0, 0.1)
                module.running_mean.normal_(0, 0.1)
                module.running_var.uniform_(0.5, 2.0)
    state = {f"features.{k}": v for k, v in features.state_dict().items()}
    state["classifier.6.bias"] = torch.zeros(1000)  # the classifier: not the encoder's, left out
    torch.save(state, path)
    return features


@pytest.mark.parametrize("batch_norm", [True, False], ids=["vgg16_bn", "vgg16"])
def test_the_encoder_computes_torchvisions_features(batch_norm: bool, tmp_path: Path) -> None:
    torch.set_num_threads(1)
    path = tmp_path / "vgg.pth"
    features = _write(path, batch_norm)
    keys = set(torch.load(path, weights_only=True))
    # torchvision's own names: the last conv of vgg16_bn is features.40 (its batch norm 41), of vgg16 features.28
    assert ({"features.40.weight", "features.41.running_var"} <= keys) == batch_norm
    assert "features.28.weight" in keys and ("features.28.running_mean" in keys) == batch_norm  # bn / conv
    assert max(torchvision_conv_indices(((64, 2), (128, 2), (256, 3), (512, 3), (512, 3)), batch_norm)) == (
        40 if batch_norm else 28
    )
    encoder = VGGEncoder(width=1.0, weights=str(path))
    assert encoder.load_weights()
    encoder.eval()
    image = torch.rand(2, 3, 32, 48)
    with torch.no_grad():
        ours = encoder(image)
        x = (image - torch.tensor(IMAGENET_MEAN).view(1, 3, 1, 1)) / torch.tensor(IMAGENET_STD).view(1, 3, 1, 1)
        theirs = []
        for module in features:
            if isinstance(module, nn.MaxPool2d):
                theirs.append(x)  # a stage's output: the block before its pool
            x = module(x)
    assert len(ours) == len(theirs) == 5
    for stage, (a, b) in enumerate(zip(ours, theirs, strict=True)):
        assert a.shape == b.shape and torch.allclose(a, b, rtol=1e-4, atol=1e-5), stage


def test_fit_starts_from_the_file_and_a_stored_model_needs_it_not(tmp_path: Path) -> None:
    from stamlane.models import STAM, LaneDecoder

    path = tmp_path / "vgg16_bn.pth"
    _write(path, batch_norm=True, seed=1)
    reference = VGGEncoder(width=1.0, weights=str(path))
    reference.load_weights()

    def module(weights: str | None) -> StamLaneModule:
        return StamLaneModule(VGGEncoder(width=1.0, weights=weights), lambda c: STAM(c), lambda c: LaneDecoder(c))

    trained = module(str(path))
    assert not torch.equal(trained.net.encoder.stages[0][0].weight, reference.stages[0][0].weight)  # not yet
    trained.setup("fit")
    for key, value in reference.stages.state_dict().items():
        assert torch.equal(trained.net.encoder.stages.state_dict()[key], value), key
    path.unlink()
    module(str(path)).setup("validate")  # built, validated without the file: only fit reads it


def test_another_layout_is_refused_in_one_line(tmp_path: Path) -> None:
    torch.manual_seed(0)
    narrow = tmp_path / "narrow.pth"  # another width: shapes differ
    torch.save({"features.0.weight": torch.zeros(32, 3, 3, 3), "features.0.bias": torch.zeros(32)}, narrow)
    with pytest.raises(ImageNetWeightsError, match=r"features.0.weight of shape \(32, 3, 3, 3\)") as err:
        VGGEncoder(width=1.0, weights=str(narrow)).load_weights()
    assert "\n" not in str(err.value)
    resnet = tmp_path / "resnet.pth"
    torch.save({"conv1.weight": torch.zeros(64, 3, 7, 7)}, resnet)
    with pytest.raises(ImageNetWeightsError, match=r"features\.0\.weight missing"):
        VGGEncoder(width=1.0, weights=str(resnet)).load_weights()
    code = tmp_path / "code.pth"
    torch.save({"features.0.weight": nn.Conv2d(3, 64, 3)}, code)  # a pickled module: weights_only refuses it
    with pytest.raises(ImageNetWeightsError, match="not a readable torch file"):
        VGGEncoder(width=1.0, weights=str(code)).load_weights()
    with pytest.raises(ImageNetWeightsError, match=r"width 1\.0"):
        VGGEncoder(width=0.25, weights=str(resnet)).load_weights()
    with pytest.raises(ImageNetWeightsError, match="do not exist"):
        VGGEncoder(weights=str(tmp_path / "missing.pth")).load_weights()


@pytest.mark.usefixtures("plain_argv")
def test_fit_with_weights_of_another_layout_exits_2(
    tiny_synthetic, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    tiny_set = tiny_synthetic(128, 72, 2, train=2, val=1, test=1, challenging=0)
    bad = tmp_path / "resnet.pth"
    torch.save({"conv1.weight": torch.zeros(64, 3, 7, 7)}, bad)
    args = tiny_args(tiny_set, tmp_path / "run", "--trainer.max_steps=1", "--model.encoder.width=1.0")
    assert main(["fit", *args, f"--model.encoder.init_args.weights={bad}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("stamlane fit: ImageNet weights") and "Traceback" not in "\n".join(err)
