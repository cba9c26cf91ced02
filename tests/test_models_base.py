"""The InbetweenModel contract, checked for every model of the registry (``MODELS``) built with the TINY sizes it
declares: a new model is one module + one conf/model yaml + one registry line, and these tests find it."""
from __future__ import annotations

import inspect
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch

from conftest import CONF_DIR, TINY_MAX_FRAMES, TINY_PARENTS, compose_cfg, tiny_model
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.models import MODELS, InbetweenModel, build_network
from inbetweening.training.config import ConfigError, validate

J = len(TINY_PARENTS)
ALL = sorted(MODELS)
TRAINABLE = [n for n in ALL if MODELS[n].trainable]


def make_batch(b=2, t=8, seed=0):
    """Masked input ``x`` (unit quaternions), per-joint ``known`` (both whole known frames and islands) and a
    stand-in interpolation ``interp``."""
    g = torch.Generator().manual_seed(seed)
    y = torch.randn(b, t, J, 7, generator=g)
    y = torch.cat([y[..., :3], y[..., 3:] / y[..., 3:].norm(dim=-1, keepdim=True)], dim=-1)
    known = torch.rand(b, t, J, generator=g) > 0.6
    known[:, :2] = True
    known[:, -1] = True
    interp = torch.randn(b, t, J, 7, generator=g)
    return y * known[..., None], known, interp


@pytest.fixture(autouse=True)
def _seed():
    torch.manual_seed(0)


# ------------------------------------------------------------------ registry
def test_registry_and_model_configs_match():
    """Every registry entry has a conf/model/<name>.yaml naming it, and every yaml a registry entry."""
    from inbetweening.models import RETARGETERS

    yamls = {p.stem for p in (Path(CONF_DIR) / "model").glob("*.yaml")}
    assert yamls == set(MODELS) | set(RETARGETERS)


@pytest.mark.parametrize("name", ALL)
def test_model_yaml_restates_the_code_defaults(name):
    """conf/model/<name>.yaml and the code never disagree: every value the yaml gives (the common arguments of
    :class:`InbetweenModel` and the model's own) is the constructor's default; the common arguments and their
    defaults are written once, in ``InbetweenModel.__init__`` (a model states only a default of its own)."""
    from omegaconf import OmegaConf

    yaml = OmegaConf.to_container(OmegaConf.load(Path(CONF_DIR) / "model" / f"{name}.yaml"))
    yaml.pop("name")
    defaults = MODELS[name].settings()
    plain = {k: list(v) if isinstance(v, tuple) else v for k, v in defaults.items()}
    assert {k: plain[k] for k in yaml} == yaml
    common = InbetweenModel.common_settings()
    if MODELS[name].trainable:
        assert set(common) - {"layout"} <= set(defaults)
    restated = set(inspect.signature(MODELS[name].__init__).parameters) & set(common)
    assert restated <= {"dropout"}, f"{name} restates common arguments {sorted(restated)} (only dropout's default differs)"


@pytest.mark.parametrize("name", [n for n in ALL if MODELS[n].trainable])
def test_unknown_constructor_arguments_are_a_type_error(name):
    with pytest.raises(TypeError, match="unexpected keyword argument 'depht'"):
        tiny_model(name, depht=3)


@pytest.mark.parametrize("name", ALL)
def test_model_config_builds_the_model(name, tmp_path):
    """The yaml's settings are all constructor settings and pass the model's checks; ``build_network`` builds it."""
    cfg = compose_cfg("train", [f"model={name}"], tmp_path, tmp_path)
    assert cfg.model.name == name
    settings = {k: v for k, v in cfg.model.items() if k != "name"}
    if not MODELS[name].accepts_any_setting():
        assert set(settings) <= set(MODELS[name].settings())
    MODELS[name].check_config(settings)
    skeleton = Skeleton([f"j{i}" for i in range(J)], TINY_PARENTS, [[0.0, 0.0, 0.0]] * J)
    net = build_network({**cfg.model, **MODELS[name].TINY}, skeleton)
    assert type(net) is MODELS[name] and isinstance(net, InbetweenModel)
    assert (sum(p.numel() for p in net.parameters()) > 0) == MODELS[name].trainable


@pytest.mark.parametrize("name", ALL)
def test_config_validation_asks_the_model(name, tmp_path):
    """A config is checked by the chosen model's own rules, the message naming ``model.<key>``."""
    cfg = compose_cfg("train", [f"model={name}", "++model.feature_dim=3"], tmp_path, tmp_path)
    with pytest.raises(ConfigError, match=r"^model.feature_dim: must be an integer >= 7, got 3$"):
        validate(cfg)


@pytest.mark.parametrize("overrides, match", [
    (["model=unet1d", "model.norm_groups=3"], r"^model.norm_groups: 3 must divide model.base_channels=64$"),
    (["model=st_transformer", "model.spatial_heads=3"], r"^model.spatial_heads: 3 must divide model.spatial_dim=32$"),
    (["model=frame_transformer", "model.norm=group"], r"^model.norm: must be one of \['layer', 'batch'\]"),
    (["model=graph_transformer", "model.graph=add"], r"^model.graph: must be one of"),
    (["model=graph_transformer", "model.hops=1.5"], r"^model.hops: must be an integer >= 0, got 1.5$"),
])
def test_model_specific_config_errors(overrides, match, tmp_path):
    with pytest.raises(ConfigError, match=match):
        validate(compose_cfg("train", overrides, tmp_path, tmp_path))


def test_rules_of_one_model_do_not_apply_to_another(tmp_path):
    """``res_blocks=0`` is a valid ResNet-LSTM (the input layer straight into the LSTM); ``heads`` need not divide
    ``d_model`` of a model without them (a setting of another model is refused as such)."""
    validate(compose_cfg("train", ["model=resnet_lstm", "model.res_blocks=0"], tmp_path, tmp_path))
    with pytest.raises(ConfigError, match=r"^model.heads: not a setting of model 'unet1d'"):
        validate(compose_cfg("train", ["model=unet1d", "+model.heads=3"], tmp_path, tmp_path))


@pytest.mark.parametrize("name", ALL)
def test_tiny_sizes_are_settings(name):
    assert set(MODELS[name].TINY) <= set(MODELS[name].settings())
    if MODELS[name].trainable:
        assert MODELS[name].TINY, "a trainable model declares small TINY sizes for the tests"
        assert tiny_model(name).output_head(), "a trainable model names its OUTPUT_HEAD"


# ------------------------------------------------------------------ forward
@pytest.mark.parametrize("residual", [False, True])
@pytest.mark.parametrize("name", ALL)
def test_shape_known_bit_exact_unit_quaternions(name, residual):
    model = tiny_model(name, residual_to_interpolation=residual).eval()
    for b, t in [(2, 8), (1, 5), (3, 13)]:  # dynamic batch and length
        x, known, interp = make_batch(b, t, seed=t)
        with torch.no_grad():
            out = model(x, known, interp)
        assert out.shape == x.shape
        assert torch.isfinite(out).all()
        assert torch.equal(out[known], x[known])
        qn = out[..., 3:7].norm(dim=-1)[~known]
        assert torch.allclose(qn, torch.ones_like(qn), atol=1e-5)


@pytest.mark.parametrize("name", ALL)
def test_known_values_bit_exact_whatever_the_unknown_input(name):
    """Known values are copied from ``x``, even when the unknown positions hold NaN (whatever the rest becomes)."""
    model = tiny_model(name).eval()
    x, known, interp = make_batch()
    x[~known] = float("nan")
    with torch.no_grad():
        out = model(x, known, interp)
    assert torch.equal(out[known], x[known])


@pytest.mark.parametrize("name", TRAINABLE)
def test_untrained_residual_model_returns_the_interpolation_exactly(name):
    model = tiny_model(name, residual_to_interpolation=True)
    assert all(torch.count_nonzero(p) == 0 for p in model.output_head())
    x, known, interp = make_batch()
    assert torch.equal(model(x, known, interp), model.finalize(interp, x, known))
    assert model(x, known).shape == x.shape  # interp stays optional


@pytest.mark.parametrize("name", TRAINABLE)
def test_gate_weighs_the_correction_per_joint_and_frame(name):
    """``gate=True``: one more output channel; untrained it is the interpolation; a closed gate (very negative logit)
    is the interpolation whatever the correction, an open one the full correction; keys stay exact; gradients reach
    the gate."""
    model = tiny_model(name, residual_to_interpolation=True, gate=True)
    assert model.output_dim == model.feature_dim + 1
    x, known, interp = make_batch()
    assert torch.equal(model(x, known, interp), model.finalize(interp, x, known))
    correction = torch.randn(*x.shape[:3], model.feature_dim)
    for logit, weight in ((-1e4, 0.0), (1e4, 1.0)):
        model.network = lambda x_, k_, i_, c=correction, g=logit: torch.cat([c, torch.full((*c.shape[:3], 1), g)], -1)
        out = model(x, known, interp)
        assert torch.allclose(out, model.finalize(interp + weight * correction, x, known))
        assert torch.equal(out[known], x[known])
    with pytest.raises(ValueError, match="gate: .* needs residual_to_interpolation=true"):
        tiny_model(name, residual_to_interpolation=False, gate=True)
    model = tiny_model(name, residual_to_interpolation=True, gate=True)
    with torch.no_grad():
        for p in model.output_head():
            p.normal_(0, 0.1)
    out = model(x, known, interp)
    out[~known].sum().backward()
    assert all(p.grad is not None and p.grad.abs().sum() > 0 for p in model.output_head())


@pytest.mark.parametrize("name", TRAINABLE)
def test_output_head_is_random_without_residual(name):
    assert any(torch.count_nonzero(p) > 0 for p in tiny_model(name).output_head())


@pytest.mark.parametrize("name", TRAINABLE)
def test_one_backward_reaches_every_parameter(name):
    model = tiny_model(name)
    x, known, interp = make_batch()
    out = model(x, known, interp)
    weights = torch.randn(out.shape, generator=torch.Generator().manual_seed(1))
    (out * weights)[~known].sum().backward()
    for pname, p in model.named_parameters():
        assert p.requires_grad and p.grad is not None and p.grad.abs().sum() > 0, pname


# ------------------------------------------------------------------ input checks
@pytest.mark.parametrize("name", ALL)
def test_wrong_input_shapes_raise(name):
    model = tiny_model(name)
    x, known, interp = make_batch()
    bad = [
        ((x[:, :, :4], known[:, :, :4], interp[:, :, :4]), "x must be"),  # other number of joints
        ((x[..., :6], known, interp[..., :6]), "x must be"),  # other feature dim
        ((x[0], known[0], interp[0]), "x must be"),  # no batch axis
        ((x, known[:, :-1], interp), "known must be"),
        ((x, known, interp[:, :-1]), "interp must have the shape of x"),
    ]
    for args, match in bad:
        with pytest.raises(ValueError, match=match):
            model(*args)


@pytest.mark.parametrize("name", ALL)
def test_max_frames(name):
    model = tiny_model(name)
    x, known, interp = make_batch(1, TINY_MAX_FRAMES)
    assert model(x, known, interp).shape == x.shape  # exactly max_frames is fine
    x, known, interp = make_batch(1, TINY_MAX_FRAMES + 1)
    if model.length_limited:
        with pytest.raises(ValueError, match=f"exceeds max_frames={TINY_MAX_FRAMES}"):
            model(x, known, interp)
    else:  # baselines work at any length
        assert model(x, known, interp).shape == x.shape


@pytest.mark.parametrize("name", ALL)
def test_invalid_common_settings_name_the_argument(name):
    for kw, match in [({"feature_dim": 3}, "feature_dim: must be an integer >= 7"),
                      ({"max_frames": 0}, "max_frames: must be an integer >= 1"),
                      ({"dropout": 1.0}, r"dropout: must be in \[0, 1\)"),
                      ({"num_joints": 0}, "num_joints: must be an integer >= 1"),
                      ({"adjacency": [[1.0] * J] * (J - 1)}, rf"adjacency: must have shape \({J}, {J}\)")]:
        with pytest.raises(ValueError, match=rf"^{MODELS[name].__name__}: {match}"):
            tiny_model(name, **kw)


# ------------------------------------------------------------------ state and export
@pytest.mark.parametrize("name", ALL)
def test_state_dict_round_trip_reproduces_the_output(name):
    a = tiny_model(name).eval()
    torch.manual_seed(1)
    b = tiny_model(name).eval()
    x, known, interp = make_batch()
    if a.trainable:
        assert not torch.equal(a(x, known, interp), b(x, known, interp))
    b.load_state_dict(a.state_dict(), strict=True)
    assert list(b.state_dict()) == list(a.state_dict())
    with torch.no_grad():
        assert torch.equal(a(x, known, interp), b(x, known, interp))


@pytest.mark.parametrize("name", TRAINABLE)  # checkpoints (what api/export.py exports) exist for trained models only
def test_onnx_export_matches_onnxruntime(name, tmp_path):
    """``net(x, known, interp)`` exported as api/export.py does (dynamic B and T), run by ONNX Runtime on other
    B and T.  The output head is re-drawn so the residual network contributes on top of ``interp``."""
    ort = pytest.importorskip("onnxruntime")
    pytest.importorskip("onnx")
    model = tiny_model(name, residual_to_interpolation=True).eval()
    with torch.no_grad():
        for p in model.output_head():
            p.normal_(0.0, 0.1)
    onnx_round_trip(ort, model, tmp_path / f"{name}.onnx")


def onnx_round_trip(ort, model, path) -> None:
    """Export ``model`` as api/export.py does (dynamic B and T) and check ONNX Runtime against PyTorch on other
    B and T."""
    axes = {k: {0: "B", 1: "T"} for k in ("x", "known", "interp", "out")}
    with warnings.catch_warnings(), torch.no_grad():
        warnings.simplefilter("ignore")
        torch.onnx.export(model, make_batch(2, 8), str(path), dynamo=False, opset_version=17,
                          input_names=["x", "known", "interp"], output_names=["out"], dynamic_axes=axes)
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    x, known, interp = make_batch(3, 13, seed=3)  # another B and T (other padding remainder for the U-Net)
    assert [i.name for i in session.get_inputs()] == ["x", "known", "interp"]
    (got,) = session.run(None, {"x": x.numpy(), "known": known.numpy(), "interp": interp.numpy()})
    with torch.no_grad():
        ref = model(x, known, interp).numpy()
    assert got.shape == ref.shape
    np.testing.assert_allclose(got, ref, atol=1e-4, rtol=0)
