"""Training: the torch SSIM against scikit-image, a few-step smoke run of each network on a tiny fake
dataset (export, ONNX equality, model card, resume), and the NaN guard."""

import hashlib
import json

import itertools

import numpy as np
import pytest
import torch
from dataset_fakes import fake_render

from wgpu_rt.dataset import DatasetConfig, TruthEngine
from wgpu_rt.models import DENOISER
from wgpu_rt.train import TrainConfig, TrainingError, train
from wgpu_rt.train.cards import without_history_tables
from wgpu_rt.train.losses import denoiser_loss, ssim
from wgpu_rt.train.networks import UNet, export_onnx
from wgpu_rt.train.samples import ANY_SPP, curriculum_spp
from wgpu_rt.train.trainer import Trainer, confidence_aucs, roc_auc


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("tiny")
    config = DatasetConfig(scenes=("cornell",), views=10, size=24, spp=(1, 4, 16), gold=32,
                           sequence_fraction=0.5)
    TruthEngine(config, out, renderer=fake_render).run(progress=False)
    return out


def test_torch_ssim_matches_scikit_image():
    from skimage.metrics import structural_similarity

    rng = np.random.default_rng(1)
    a = rng.uniform(size=(3, 32, 40))
    b = np.clip(a + rng.normal(0, 0.1, a.shape), 0, 1)
    reference = structural_similarity(a, b, channel_axis=0, data_range=1.0, gaussian_weights=True, sigma=1.5,
                                      use_sample_covariance=False)
    ours = ssim(torch.from_numpy(a[None]), torch.from_numpy(b[None]))
    assert float(ours) == pytest.approx(reference, abs=1e-6)


def with_albedo_factor(log_irradiance: torch.Tensor) -> torch.Tensor:
    """A denoiser target: log1p irradiance + a random albedo factor in [0.01, 1.01]."""
    return torch.cat([log_irradiance, 0.01 + torch.rand_like(log_irradiance)], dim=1)


def test_denoiser_loss_is_zero_only_at_the_target_and_differentiable():
    log_irradiance = torch.rand(2, 3, 16, 16)
    target = with_albedo_factor(log_irradiance)
    assert float(denoiser_loss(log_irradiance, target)) == pytest.approx(0.0, abs=1e-6)
    guess = (log_irradiance + 0.1 * torch.randn_like(log_irradiance)).requires_grad_()
    loss = denoiser_loss(guess, target, "charbonnier")
    loss.backward()
    assert float(loss.detach()) > 0 and torch.isfinite(guess.grad).all() and guess.grad.abs().sum() > 0


def test_display_mapping_matches_the_metrics_one():
    from wgpu_rt.metrics import to_display
    from wgpu_rt.train.losses import log_to_display

    log_color = np.array([0.0, 0.01, 0.3, 1.0, 3.0, 9.0])
    np.testing.assert_allclose(log_to_display(torch.from_numpy(log_color)).numpy(), to_display(np.expm1(log_color)),
                               atol=6e-3)
    assert float(log_to_display(torch.tensor(-1.0))) == 0.0


def test_display_space_loss_is_zero_only_at_the_target_and_has_gradients_at_black():
    log_irradiance = torch.rand(2, 3, 16, 16)
    target = with_albedo_factor(log_irradiance)
    assert float(denoiser_loss(log_irradiance, target, ssim_space="display")) == pytest.approx(0.0, abs=1e-6)
    guess = torch.zeros_like(log_irradiance).requires_grad_()
    denoiser_loss(guess, target, ssim_space="display").backward()
    assert torch.isfinite(guess.grad).all() and guess.grad.abs().sum() > 0


def test_block_mean_term_adds_the_l1_of_8x8_block_means_of_the_compared_colours():
    """lowpass·L1 between the 8×8 block means of the display colours on top of the usual loss: zero at
    the target; a shift of one block's mean costs that shift (in display values) times the weight, over
    the number of blocks."""
    from wgpu_rt.train.losses import log_to_display, remodulate

    log_irradiance = 0.5 + 0.2 * torch.rand(1, 3, 16, 16)
    target = with_albedo_factor(log_irradiance)
    assert float(denoiser_loss(log_irradiance, target, ssim_space="display", lowpass=3.0)) == pytest.approx(0.0, abs=1e-6)
    shifted = log_irradiance.clone()
    shifted[..., :8, :8] += 0.3
    base = denoiser_loss(shifted, target, ssim_space="display")
    display = lambda x: log_to_display(remodulate(x, target[:, 3:]))   # noqa: E731
    block_shift = (display(shifted) - display(log_irradiance))[..., :8, :8].mean(dim=(2, 3)).abs().mean() / 4
    assert float(denoiser_loss(shifted, target, ssim_space="display", lowpass=3.0) - base) == \
        pytest.approx(3.0 * float(block_shift), rel=1e-4)


def test_log_mse_term_adds_the_mean_of_each_crops_log_display_mse():
    """log_mse·mean over crops of log10(1 + MSE / 1e-6) of the display colours on top of the usual loss, in
    either SSIM space: zero at the target; with two crops off by different amounts, the mean of their two logs
    (not the log of the batch's MSE). A negative or non-finite weight is refused before any work."""
    from wgpu_rt.train.losses import LOG_MSE_FLOOR, log_to_display, remodulate

    log_irradiance = 0.5 + 0.2 * torch.rand(2, 3, 16, 16)
    target = with_albedo_factor(log_irradiance)
    assert float(denoiser_loss(log_irradiance, target, log_mse=0.5)) == pytest.approx(0.0, abs=1e-6)
    shifted = log_irradiance.clone()
    shifted[0] += 0.001
    shifted[1] += 0.01
    display = lambda x: log_to_display(remodulate(x, target[:, 3:]))   # noqa: E731
    mse = ((display(shifted) - display(log_irradiance)) ** 2).mean(dim=(1, 2, 3))
    expected = float(np.log10(1.0 + mse.numpy() / LOG_MSE_FLOOR).mean())
    for space in ("log", "display"):
        base = denoiser_loss(shifted, target, ssim_space=space)
        assert float(denoiser_loss(shifted, target, ssim_space=space, log_mse=0.5) - base) == \
            pytest.approx(0.5 * expected, rel=1e-4)
    for flag, weight in (("lowpass", -1.0), ("log_mse", float("nan"))):
        with pytest.raises(TrainingError, match=f"--{flag.replace('_', '-')} must be a loss weight"):
            TrainConfig(task="denoiser", data="unused", **{flag: weight}).check()


def test_edge_term_adds_the_display_l1_within_two_pixels_of_an_aux_edge():
    """edge·mean |display difference| over the pixels within 2 px of a step in the albedo, normal or depth
    planes, on top of the usual loss: zero at the target; an error inside the marked band counts in full,
    one elsewhere not at all; flat aux planes (or noise below the step) mark nothing. A negative weight is
    refused before any work."""
    from wgpu_rt.train.losses import aux_edges, log_to_display, remodulate

    aux = torch.full((1, 7, 16, 16), 0.5)
    aux[:, 6] = 0.3                                             # depth
    aux[:, 4, :, 8:] = 0.9                                      # a normal plane steps between columns 7 and 8
    aux[:, 6, 12:, :] = 0.36                                    # depth steps 20 % between rows 11 and 12
    marked = aux_edges(aux)[0, 0]
    expected = torch.zeros(16, 16)
    expected[:, 6:10] = 1
    expected[10:14, :] = 1
    assert torch.equal(marked, expected)
    flat = torch.full((1, 7, 16, 16), 0.5) + 0.04 * torch.rand(1, 7, 16, 16)
    flat[:, 6] = 0.5 + 0.01 * torch.rand(16, 16)               # depth within 2 %
    assert float(aux_edges(flat).sum()) == 0.0

    log_irradiance = 0.5 + 0.2 * torch.rand(1, 3, 16, 16)
    target = with_albedo_factor(log_irradiance)
    assert float(denoiser_loss(log_irradiance, target, edge=2.0, aux=aux)) == pytest.approx(0.0, abs=1e-6)
    display = lambda x: log_to_display(remodulate(x, target[:, 3:]))   # noqa: E731
    for rows, cols, inside in ((slice(0, 4), slice(6, 10), True), (slice(0, 4), slice(0, 4), False)):
        shifted = log_irradiance.clone()
        shifted[..., rows, cols] += 0.2
        base = denoiser_loss(shifted, target, ssim_space="display")
        added = float(denoiser_loss(shifted, target, ssim_space="display", edge=2.0, aux=aux) - base)
        shift = float((display(shifted) - display(log_irradiance)).abs().sum() / (3 * expected.sum()))
        assert added == pytest.approx(2.0 * shift if inside else 0.0, rel=1e-4, abs=1e-7)
    with pytest.raises(TrainingError, match="--edge must be a loss weight"):
        TrainConfig(task="denoiser", data="unused", edge=-0.5).check()


def test_the_trainer_gives_the_edge_term_the_inputs_albedo_normal_and_depth_planes(tiny_dataset, tmp_path):
    """With --edge the trainer's loss is denoiser_loss with the input's planes 3–9 as its aux (the layout
    pack_denoiser_input writes); without it, no edge term."""
    from wgpu_rt.train.samples import Augmentation

    config = dict(task="denoiser", data=str(tiny_dataset), out=str(tmp_path), epochs=1, batch=2, crop_min=12,
                  crop_max=16, widths=(4, 8), ssim_space="display")
    trainer = Trainer(TrainConfig(**config, edge=2.0), progress=False)
    x, y = trainer.train_set.batch(trainer.train_set.items[:2], np.random.default_rng(0), Augmentation(16, 16), 1)
    prediction = y[:, :3] + 0.1 * torch.rand(y[:, :3].shape)
    with_edge = float(trainer.loss(prediction, y, x))
    assert with_edge == pytest.approx(float(denoiser_loss(prediction, y, ssim_space="display", edge=2.0,
                                                          aux=x[:, 3:10])), rel=1e-6)
    plain = Trainer(TrainConfig(**config), progress=False)
    without_edge = float(plain.loss(prediction, y, x))
    assert without_edge == pytest.approx(float(denoiser_loss(prediction, y, ssim_space="display")))
    assert with_edge > without_edge


def test_denoiser_loss_scores_remodulated_colour_against_skimage():
    """0.8·(1 − SSIM of the display colours, irradiance × albedo factor) + 0.2·L1 on log1p irradiance,
    recomputed with numpy, the metrics' display mapping and scikit-image's SSIM."""
    from skimage.metrics import structural_similarity

    from wgpu_rt.metrics import to_display

    rng = np.random.default_rng(3)
    target = rng.uniform(0, 2, (3, 32, 32))
    guess = np.clip(target + rng.normal(0, 0.3, target.shape), 0, None)
    factor = rng.uniform(0.01, 1.01, target.shape)
    shown = [to_display(np.expm1(v) * factor) for v in (guess, target)]
    reference = 0.8 * (1 - structural_similarity(*shown, channel_axis=0, data_range=1.0, gaussian_weights=True,
                                                 sigma=1.5, use_sample_covariance=False))
    reference += 0.2 * np.abs(guess - target).mean()
    ours = denoiser_loss(torch.tensor(guess[None], dtype=torch.float32),
                         torch.tensor(np.concatenate([target, factor])[None], dtype=torch.float32),
                         ssim_space="display")
    assert float(ours) == pytest.approx(reference, abs=5e-3)


def test_curriculum_goes_16_then_4_then_1():
    assert [curriculum_spp(p, [1, 4, 16]) for p in (0.0, 0.3, 0.4, 0.6, 0.7, 0.99)] == [16, 16, 4, 4, 1, 1]
    assert curriculum_spp(0.0, [1, 4]) == 4


def test_curriculum_stages_can_be_weighted():
    stages = (16, 4, 1, 1)
    assert [curriculum_spp(p, [1, 4, 16], stages) for p in (0.0, 0.3, 0.49, 0.5, 0.99)] == [16, 4, 4, 1, 1]


def test_curriculum_any_stage_is_kept_whatever_the_first_view_has():
    assert [curriculum_spp(p, [1], (1, ANY_SPP)) for p in (0.0, 0.6)] == [1, ANY_SPP]
    assert curriculum_spp(0.0, [], (16, 4)) == ANY_SPP     # the views share no sample count


def test_a_fixed_stage_needs_every_view_to_have_it(tmp_path):
    """Datasets with other spp lists train together: a stage only some views have is skipped (the first
    view's list is not the dataset's)."""
    for name, spp in (("a", (1, 4)), ("b", (1,))):
        config = DatasetConfig(scenes=("cornell",), views=3, size=16, spp=spp, gold=8, sequence_fraction=0.0)
        TruthEngine(config, tmp_path / name, renderer=fake_render).run(progress=False)
    trainer = Trainer(TrainConfig(task="denoiser", data=str(tmp_path / "a"), extra_data=(str(tmp_path / "b"),),
                                  out=str(tmp_path / "m"), epochs=2, batch=2, crop_min=12, crop_max=16,
                                  widths=(4, 8), curriculum=(4, 1)), progress=False)
    trainer.run()
    assert [h["spp"] for h in trainer.history] == [1, 1]


def test_batches_hold_frames_of_one_crop_limit(tmp_path, monkeypatch):
    """Datasets of two frame sizes train together with each batch drawn from frames of one crop limit
    (a batch's crop fits its smallest frame, so mixed batches would train the large frames at the small
    ones' crops, as the H200 fine-tunes of sessions 23 and 26 did): only the epoch's last batch may mix
    the part-full runs, and every item is still drawn once an epoch."""
    from wgpu_rt.train.samples import grouped_by_crop

    for name, size in (("small", 16), ("large", 32)):
        config = DatasetConfig(scenes=("cornell",), views=8, size=size, spp=(1,), gold=8, sequence_fraction=0.0)
        TruthEngine(config, tmp_path / name, renderer=fake_render).run(progress=False)
    trainer = Trainer(TrainConfig(task="denoiser", data=str(tmp_path / "small"), extra_data=(str(tmp_path / "large"),),
                                  out=str(tmp_path / "m"), epochs=3, batch=2, crop_min=12, crop_max=32,
                                  widths=(4, 8)), progress=False)
    batches, step = [], trainer.train_step
    monkeypatch.setattr(trainer, "train_step", lambda items, spp: batches.append(items) or step(items, spp))
    trainer.run()
    items = trainer.train_set.items
    limits = [{trainer.train_set.crop_limit(item, trainer.augmentation) for item in batch} for batch in batches]
    assert set.union(*limits) == {16, 32}
    per_epoch = len(batches) // 3
    for epoch in range(3):
        drawn = batches[epoch * per_epoch:(epoch + 1) * per_epoch]
        assert sorted(item for batch in drawn for item in batch) == sorted(items)
        assert all(len(limit) == 1 for limit in limits[epoch * per_epoch:(epoch + 1) * per_epoch - 1])
    order = np.arange(len(items))
    assert np.array_equal(grouped_by_crop(order, np.full(len(items), 32), 2), order)   # one limit: as it was
    small = sum(1 for item in items if trainer.train_set.crop_limit(item, trainer.augmentation) == 16)
    assert (f"each batch from frames of one crop limit: {small} frames up to 16 px, {len(items) - small} frames up "
            f"to 32 px" in trainer.model_card())


def test_the_progress_bar_shows_the_loss_every_so_many_steps(tiny_dataset, tmp_path, monkeypatch, capsys):
    """On a terminal the bar shows a step's loss once every PROGRESS_LOSS_STEPS steps within an epoch (reading
    it waits for the device), then the epoch's mean; piped into a log there is no bar and nothing is read for
    one, and each epoch is still a line."""
    import sys

    import tqdm

    from wgpu_rt.train import trainer as trainer_module

    shown = []
    monkeypatch.setattr(tqdm.tqdm, "set_postfix", lambda bar, **values: shown.append(values))
    monkeypatch.setattr(trainer_module, "PROGRESS_LOSS_STEPS", 2)
    config = dict(task="error-predictor", data=str(tiny_dataset), epochs=1, batch=2, crop_min=8, crop_max=16)
    for terminal in (True, False):
        monkeypatch.setattr(sys.stderr, "isatty", lambda: terminal)
        shown.clear()
        trainer = Trainer(TrainConfig(out=str(tmp_path / str(terminal)), **config), progress=True)
        trainer.run()
        steps = trainer.steps_per_epoch
        assert steps >= 4 and len(shown) == (steps // 2 + 1 if terminal else 1)
        assert all(set(values) == {"loss", "spp"} for values in shown)
        printed = capsys.readouterr()
        assert printed.out.startswith("epoch 1: train_loss") and ("train error-predictor" in printed.err) == terminal


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA torch (a lent GPU's test run)")
def test_cuda_training_fuses_adam_and_leaves_cudnn_untuned(tiny_dataset, tmp_path):
    """On CUDA one fused kernel updates the parameters, and cuDNN picks kernels by its heuristics instead of
    re-tuning for every crop shape (BENCHMARKS.md §26); a run trains."""
    trainer = Trainer(TrainConfig(task="denoiser", data=str(tiny_dataset), out=str(tmp_path), epochs=1, batch=2,
                                  crop_min=12, crop_max=16, widths=(4, 8), device="cuda"), progress=False)
    assert trainer.optimizer.defaults["fused"] and not torch.backends.cudnn.benchmark
    assert np.isfinite(trainer.run()["train_loss"])


def test_validation_every_n_epochs_and_after_the_last(tiny_dataset, tmp_path):
    trainer = Trainer(TrainConfig(task="error-predictor", data=str(tiny_dataset), out=str(tmp_path), epochs=5,
                                  batch=2, crop_min=8, crop_max=16, validate_every=2), progress=False)
    trainer.run()
    assert [h["epoch"] for h in trainer.history if "val_spearman" in h] == [2, 4, 5]
    card = trainer.model_card()
    rows = [line for line in card.split("## History")[1].splitlines() if line[2:3].isdigit()]
    assert [int(row.split("|")[1]) for row in rows] == [1, 2, 4, 5]    # the first, the validated, the last
    assert rows[0].endswith("| — |")    # epoch 1: not validated
    epochs_3_and_4 = np.mean([h["train_loss"] for h in trainer.history[2:4]])
    assert float(rows[2].split("|")[4]) == pytest.approx(epochs_3_and_4, abs=6e-5)


def test_a_base_cards_history_tables_are_left_out():
    card = "# m\n\n## Data\n- x\n| not history |\n\n## History\n\n| epoch |\n| --- |\n| 1 |\n\n" \
           "## Base model\n\n### History\n\n| 7 |\n"
    assert without_history_tables(card).splitlines() == [
        "# m", "", "## Data", "- x", "| not history |", "", "## History", "", "", "## Base model", "",
        "### History"]


@pytest.mark.parametrize("minutes, epochs_run", [(1e-9, 1), (600.0, 4)])
def test_a_time_budget_cuts_the_epochs_and_the_schedule_still_ends(tiny_dataset, tmp_path, minutes, epochs_run):
    """--minutes: a budget spent by the first epoch ends the run after it, validated, with the learning
    rate decayed to its end and the card saying why; a budget that fits changes nothing."""
    trainer = Trainer(TrainConfig(task="error-predictor", data=str(tiny_dataset), out=str(tmp_path), epochs=4,
                                  batch=2, crop_min=8, crop_max=16, validate_every=3, minutes=minutes),
                      progress=False)
    trainer.run()
    assert trainer.epoch == trainer.config.epochs == epochs_run
    assert trainer.step == trainer.total_steps == trainer.steps_per_epoch * epochs_run
    assert "val_spearman" in trainer.history[-1]
    assert trainer.learning_rate_factor(trainer.step) == pytest.approx(0.0, abs=1e-12)
    assert ("of 4 asked: cut to fit --minutes" in trainer.model_card()) == (epochs_run < 4)
    with pytest.raises(TrainingError, match="--minutes must be a positive number"):
        TrainConfig(task="denoiser", data=str(tiny_dataset), minutes=0).check()


def test_resume_refuses_a_checkpoint_trained_with_other_settings(tiny_dataset, tmp_path):
    base = dict(task="denoiser", data=str(tiny_dataset), out=str(tmp_path), widths=(4, 8))
    Trainer(TrainConfig(epochs=1, **base), progress=False).run()
    with pytest.raises(TrainingError, match="ssim_space"):
        Trainer(TrainConfig(epochs=2, resume=True, ssim_space="display", **base), progress=False)


def test_residual_unet_adds_its_correction_to_the_input_colour():
    from wgpu_rt.train.networks import UNet

    torch.manual_seed(3)
    net = UNet(widths=(4, 8), residual=True).eval()
    x = torch.rand(1, DENOISER.input_channels, 16, 16)
    with torch.no_grad():
        np.testing.assert_array_equal(net(x).numpy(), x[:, :3].numpy())   # zero-initialised correction
        torch.nn.init.normal_(net.head.weight)
        correction = UNet(widths=(4, 8))
        correction.load_state_dict({k: v for k, v in net.state_dict().items() if k != "input_selector"})
        np.testing.assert_allclose(net(x).numpy(), (x[:, :3] + correction(x)).numpy(), atol=1e-6)


def test_extra_data_joins_training_and_validation_but_never_its_test_split(tiny_dataset, tmp_path):
    extra = tmp_path / "extra"
    TruthEngine(DatasetConfig(scenes=("cornell",), views=10, size=24, spp=(1, 4, 16), gold=32, seed=1,
                              sequence_fraction=0.0), extra, renderer=fake_render).run(progress=False)
    base = dict(task="denoiser", data=str(tiny_dataset), out=str(tmp_path), widths=(4, 8))
    alone = Trainer(TrainConfig(**base), progress=False)
    joined = Trainer(TrainConfig(extra_data=(str(extra),), **base), progress=False)
    splits = lambda samples: [v.split for v in samples.views]  # noqa: E731
    assert len(joined.train_set.views) == len(alone.train_set.views) + 8
    assert len(joined.val_set.views) == len(alone.val_set.views) + 1
    assert set(splits(joined.train_set)) == {"train"} and set(splits(joined.val_set)) == {"val"}
    card = joined.model_card()   # names both folders
    assert f"`{tiny_dataset}`" in card and f"`{extra}`" in card


def test_roc_auc_against_brute_force_pair_counting():
    rng = np.random.default_rng(2)
    scores, labels = rng.uniform(size=60), rng.uniform(size=60) > 0.6
    pairs = [(p > n) + 0.5 * (p == n) for p in scores[labels] for n in scores[~labels]]
    assert roc_auc(scores, labels) == pytest.approx(np.mean(pairs))


def pair_counting_auc(scores, labels) -> float:
    """ROC AUC by brute force: the share of (positive, negative) pairs ranked right, ties half."""
    scores, labels = np.ravel(scores), np.ravel(labels) > 0.5
    return float(np.mean([(p > n) + 0.5 * (p == n) for p in scores[labels] for n in scores[~labels]]))


def test_confidence_aucs_over_all_tested_and_stage_pixels():
    """The tested-pixel AUC ignores untested pixels; the stage's counts them as certain disocclusion."""
    rng = np.random.default_rng(5)
    confidence, mask = rng.uniform(size=(6, 7)), (rng.uniform(size=(6, 7)) > 0.6).astype(np.float32)
    tested = rng.uniform(size=(6, 7)) > 0.3
    aucs = confidence_aucs(confidence, mask, tested)
    assert aucs["roc_auc"] == pytest.approx(pair_counting_auc(1 - confidence, mask))
    assert aucs["roc_auc_tested"] == pytest.approx(pair_counting_auc(1 - confidence[tested], mask[tested]))
    assert aucs["roc_auc_stage"] == pytest.approx(pair_counting_auc(np.where(tested, 1 - confidence, 1.0), mask))
    assert len({round(v, 6) for v in aucs.values()}) == 3


@pytest.mark.parametrize("task", ["denoiser", "error-predictor", "confidence"])
def test_smoke_training_exports_a_model_equal_to_torch(task, tiny_dataset, tmp_path):
    import onnxruntime

    config = TrainConfig(task=task, data=str(tiny_dataset), out=str(tmp_path), epochs=1, batch=2,
                         crop_min=12, crop_max=16, widths=(4, 8))
    if task == "confidence":   # it learns on the denoised frame: OUT/denoiser.onnx makes it
        export_onnx(UNet(widths=(4, 8)), tmp_path / "denoiser.onnx")
    summary = train(config, progress=False)
    card = (tmp_path / f"{config.model_name}.md").read_text()
    assert "## Validation" in card and "training views" in card
    key = {"denoiser": "val_psnr", "error-predictor": "val_spearman", "confidence": "val_roc_auc"}[task]
    assert np.isfinite(summary["metrics"][key])
    trainer = Trainer(config, progress=False)
    trainer._load_checkpoint()
    x, _ = trainer.val_set.full(trainer.val_set.items[0], 1, 1.0)
    session = onnxruntime.InferenceSession(summary["onnx"], providers=["CPUExecutionProvider"])
    exported = session.run(None, {"input": x[None]})[0][0]
    np.testing.assert_allclose(exported, trainer.predict(x), atol=1e-4)


@pytest.mark.parametrize("setting", ["on", "off"])
def test_a_denoisers_onnx_records_whether_it_trained_with_the_exposure_step(setting, tiny_dataset, tmp_path):
    """`wgpu-rt train denoiser --auto-exposure on|off` packs its inputs so and writes it into the ONNX file,
    which the engine's model and the OnnxDenoiser read back (`--auto-exposure auto` then does the same); the
    card says it."""
    from wgpu_rt.frame.denoise import load_model
    from wgpu_rt.frame.denoise_chain import trained_auto_exposure
    from wgpu_rt.cli import main
    from wgpu_rt.frame.pack import pack_denoiser_input, white_balance_gains
    from wgpu_rt.train.samples import OnnxDenoiser

    out = tmp_path / setting
    assert main(["train", "denoiser", "--data", str(tiny_dataset), "--out", str(out), "--epochs", "1", "--batch",
                 "2", "--crop", "12", "16", "--widths", "4", "8", "--auto-exposure", setting, "--quiet"]) == 0
    wanted = setting == "on"
    assert trained_auto_exposure(load_model("denoiser", "fp32", path=out / "denoiser.onnx")) == wanted
    assert OnnxDenoiser(out / "denoiser.onnx").auto_exposure == wanted
    assert ("exposure scale" in (out / "denoiser.md").read_text()) == wanted
    trainer = Trainer(TrainConfig(task="denoiser", data=str(tiny_dataset), out=str(out), widths=(4, 8),
                                  auto_exposure=wanted), progress=False)
    x, _ = trainer.train_set.full(trainer.train_set.items[0], 1, 1.0)
    noisy = trainer.train_set.views[0].frames[0].noisy[1]
    gains = white_balance_gains(noisy["color"], noisy["albedo"], exposure=wanted)
    np.testing.assert_allclose(x, pack_denoiser_input(noisy["color"], noisy["albedo"], noisy["normal"],
                                                      noisy["depth"], balance=gains), rtol=2e-6, atol=1e-6)


@pytest.mark.parametrize("setting", ["on", "off"])
def test_an_error_predictors_onnx_records_whether_it_trained_with_the_exposure_step(setting, tiny_dataset, tmp_path):
    """`wgpu-rt train error-predictor --auto-exposure on|off` reads its probes at PROBE_KEY or as they are
    and says so in the ONNX file (the frame pipeline reads it back) and the card."""
    from wgpu_rt.cli import main
    from wgpu_rt.frame.denoise import load_model
    from wgpu_rt.frame.denoise_chain import trained_auto_exposure

    out = tmp_path / setting
    assert main(["train", "error-predictor", "--data", str(tiny_dataset), "--out", str(out), "--epochs", "1",
                 "--batch", "2", "--crop", "8", "16", "--auto-exposure", setting, "--quiet"]) == 0
    wanted = setting == "on"
    assert trained_auto_exposure(load_model("error_predictor", "fp32", path=out / "error_predictor.onnx")) == wanted
    assert ("exposure scale" in (out / "error_predictor.md").read_text()) == wanted


def test_resume_continues_from_the_checkpoint(tiny_dataset, tmp_path):
    base = dict(task="error-predictor", data=str(tiny_dataset), out=str(tmp_path), batch=2, crop_min=8,
                crop_max=16)
    train(TrainConfig(epochs=1, **base), progress=False)
    resumed = Trainer(TrainConfig(epochs=2, resume=True, **base), progress=False)
    assert resumed.epoch == 1 and resumed.step == resumed.steps_per_epoch
    resumed.run()
    assert [h["epoch"] for h in resumed.history] == [1, 2]


def test_fine_tune_starts_from_another_runs_weights_and_credits_its_time(tiny_dataset, tmp_path):
    base = dict(task="denoiser", data=str(tiny_dataset), out=str(tmp_path), batch=2, crop_min=12, crop_max=16,
                widths=(4, 8))
    first = Trainer(TrainConfig(epochs=1, **base), progress=False)
    first.run()
    tuned = Trainer(TrainConfig(epochs=1, curriculum=(1,), lr=1e-4, init_from=str(first.checkpoint_path),
                                checkpoints=str(tmp_path / "tuned"), **base), progress=False)
    for name, weight in first.model.state_dict().items():
        assert torch.equal(tuned.model.state_dict()[name], weight), name
    assert tuned.epoch == 0 and tuned.history == []          # fresh schedule and history
    tuned.run()
    card = tuned.model_card()
    assert f"fine-tuned from `{first.checkpoint_path}`: 1 epochs" in card and "for the run(s) it was" in card
    with pytest.raises(TrainingError, match="own checkpoint"):
        Trainer(TrainConfig(epochs=1, init_from=str(first.checkpoint_path), **base), progress=False)
    with pytest.raises(TrainingError, match="cannot start from"):
        Trainer(TrainConfig(epochs=1, init_from=str(first.checkpoint_path), checkpoints=str(tmp_path / "wide"),
                            **{**base, "widths": (4, 16)}), progress=False)


def test_fine_tune_starts_from_an_exported_model(tiny_dataset, tmp_path):
    """--init-from an .onnx (e.g. the shipped denoiser): its weights, by the parameter names torch's export
    keeps; a model neither wider nor narrower at every level is refused by name."""
    torch.manual_seed(3)
    source = UNet(widths=(4, 8))
    onnx_path = export_onnx(source, tmp_path / "exported.onnx")
    base = dict(task="denoiser", data=str(tiny_dataset), out=str(tmp_path / "out"), batch=2, crop_min=12,
                crop_max=16, widths=(4, 8))
    tuned = Trainer(TrainConfig(epochs=1, init_from=str(onnx_path), **base), progress=False)
    for name, weight in source.state_dict().items():
        assert torch.equal(tuned.model.state_dict()[name].cpu(), weight), name
    with pytest.raises(TrainingError, match="not a denoiser with these --widths"):
        Trainer(TrainConfig(epochs=1, init_from=str(onnx_path), **{**base, "widths": (2, 16)}), progress=False)


def test_a_fine_tune_of_a_model_without_the_spp_plane_starts_as_that_model(tiny_dataset, tmp_path):
    """A denoiser exported before the sample-count input (10 channels) fine-tunes into the 11-input network
    with zero weights on the new plane: it computes what the base model computed, whatever the spp."""
    torch.manual_seed(5)
    source = UNet(in_channels=DENOISER.input_channels - 1, widths=(4, 8)).eval()
    onnx_path = export_onnx(source, tmp_path / "ten_inputs.onnx")
    tuned = Trainer(TrainConfig(task="denoiser", data=str(tiny_dataset), out=str(tmp_path / "out"), epochs=1,
                                batch=2, crop_min=12, crop_max=16, widths=(4, 8), init_from=str(onnx_path)),
                    progress=False)
    x = torch.rand(2, DENOISER.input_channels, 16, 16)
    with torch.no_grad():
        np.testing.assert_allclose(tuned.model.eval().cpu()(x).numpy(), source(x[:, :-1]).numpy(), atol=1e-6)


@pytest.mark.parametrize("bottom_merge", ["concat", "add"])
def test_a_fine_tune_one_level_deeper_starts_as_the_shallower_model_and_trains_the_new_level(
        tiny_dataset, tmp_path, bottom_merge):
    """--widths with one more level than the base model's: the old levels keep their weights and what
    comes up from the new level starts with no influence (a concat merge passes the old bottom through,
    an add merge gets a zero transposed conv), so the deeper network starts as exactly the base model;
    the weights that let the new level in get a gradient at once."""
    torch.manual_seed(6)
    source = UNet(widths=(4, 8)).eval()
    onnx_path = export_onnx(source, tmp_path / "two_levels.onnx")
    tuned = Trainer(TrainConfig(task="denoiser", data=str(tiny_dataset), out=str(tmp_path / "out"), epochs=1,
                                batch=2, crop_min=12, crop_max=16, widths=(4, 8, 8), bottom_merge=bottom_merge,
                                init_from=str(onnx_path)),
                    progress=False)
    x = torch.rand(2, DENOISER.input_channels, 16, 16)
    with torch.no_grad():
        np.testing.assert_allclose(tuned.model.eval().cpu()(x).numpy(), source(x).numpy(), atol=1e-6)
    assert torch.equal(tuned.model.state_dict()["up.1.weight"], source.state_dict()["up.0.weight"])
    tuned.model.train()
    tuned.model(x).square().mean().backward()
    gate = tuned.model.merge[0][0].weight.grad[:, :8] if bottom_merge == "concat" else tuned.model.up[0].weight.grad
    assert gate.abs().sum() > 0
    with pytest.raises(TrainingError, match="not a denoiser with these --widths"):   # two levels deeper
        Trainer(TrainConfig(task="denoiser", data=str(tiny_dataset), out=str(tmp_path / "out2"), epochs=1,
                            batch=2, crop_min=16, crop_max=16, widths=(4, 8, 8, 8), init_from=str(onnx_path)),
                progress=False)


def _embedded(narrow: UNet, wide: UNet) -> UNet:
    """``wide`` holding ``narrow``'s weights in its leading channels (a concat merge's skip half at its
    own offset) and zeros elsewhere: the same function in more channels."""
    state = {}
    for name, target in wide.state_dict().items():
        source, value = narrow.state_dict()[name], torch.zeros_like(target)
        if name.startswith("merge.") and name.endswith(".0.weight"):   # cat([from below, skip])
            half, narrow_half = target.shape[1] // 2, source.shape[1] // 2
            value[:source.shape[0], :narrow_half] = source[:, :narrow_half]
            value[:source.shape[0], half:half + narrow_half] = source[:, narrow_half:]
        else:
            value[tuple(slice(0, size) for size in source.shape)] = source
        state[name] = value
    wide.load_state_dict(state)
    return wide


@pytest.mark.parametrize("bottom_merge", ["concat", "add"])
def test_a_fine_tune_into_narrower_widths_keeps_the_channels_that_matter(tiny_dataset, tmp_path, bottom_merge):
    """--widths narrower than the base model's at every level: each activation keeps the channels whose
    filters weigh most, and each layer reads the channels its producers kept, so a wide network whose
    extra channels are all zero starts the fine-tune as exactly the narrow one it holds."""
    torch.manual_seed(8)
    narrow = UNet(widths=(4, 6, 8), bottom_merge=bottom_merge).eval()
    wide = _embedded(narrow, UNet(widths=(6, 8, 12), bottom_merge=bottom_merge)).eval()
    x = torch.rand(2, DENOISER.input_channels, 16, 16)
    with torch.no_grad():
        np.testing.assert_allclose(wide(x).numpy(), narrow(x).numpy(), atol=1e-6)
    onnx_path = export_onnx(wide, tmp_path / "wide.onnx")
    tuned = Trainer(TrainConfig(task="denoiser", data=str(tiny_dataset), out=str(tmp_path / "out"), epochs=1,
                                batch=2, crop_min=12, crop_max=16, widths=(4, 6, 8), bottom_merge=bottom_merge,
                                init_from=str(onnx_path)),
                    progress=False)
    with torch.no_grad():
        np.testing.assert_allclose(tuned.model.eval().cpu()(x).numpy(), narrow(x).numpy(), atol=1e-6)
    with pytest.raises(TrainingError, match="not a denoiser with these --widths"):   # wider at one level only
        Trainer(TrainConfig(task="denoiser", data=str(tiny_dataset), out=str(tmp_path / "out2"), epochs=1,
                            batch=2, crop_min=12, crop_max=16, widths=(8, 6, 8), bottom_merge=bottom_merge,
                            init_from=str(onnx_path)), progress=False)


@pytest.mark.parametrize("bottom_merge", ["concat", "add"])
def test_a_fine_tune_into_wider_widths_starts_as_the_narrow_model_and_trains_the_new_channels(
        tiny_dataset, tmp_path, bottom_merge):
    """--widths wider than the base model's at some levels: the old channels keep their weights and
    indices, the new channels are computed (fresh filters, not zero) but read by nothing, so the wide
    network starts as exactly the narrow one, and the taps that would read the new channels get a
    gradient at once."""
    torch.manual_seed(9)
    narrow = UNet(widths=(4, 6, 8), bottom_merge=bottom_merge).eval()
    onnx_path = export_onnx(narrow, tmp_path / "narrow.onnx")
    tuned = Trainer(TrainConfig(task="denoiser", data=str(tiny_dataset), out=str(tmp_path / "out"), epochs=1,
                                batch=2, crop_min=12, crop_max=16, widths=(8, 6, 12), bottom_merge=bottom_merge,
                                init_from=str(onnx_path)),
                    progress=False)
    wide = tuned.model.eval().cpu()
    x = torch.rand(2, DENOISER.input_channels, 16, 16)
    with torch.no_grad():
        np.testing.assert_allclose(wide(x).numpy(), narrow(x).numpy(), atol=1e-6)
        features = wide.down[0](x)
    assert features[:, 4:].abs().sum() > 0                        # the new channels carry something
    state = wide.state_dict()
    assert torch.equal(state["down.0.0.weight"][:4], narrow.state_dict()["down.0.0.weight"])
    assert not state["down.0.2.weight"][:, 4:].any() and not state["head.weight"][:, 4:].any()
    wide.train()
    wide(x).square().mean().backward()
    assert wide.head.weight.grad[:, 4:].abs().sum() > 0
    with pytest.raises(TrainingError, match="not a denoiser with these --widths"):   # and one level deeper
        Trainer(TrainConfig(task="denoiser", data=str(tiny_dataset), out=str(tmp_path / "out2"), epochs=1,
                            batch=2, crop_min=16, crop_max=16, widths=(8, 6, 12, 12), bottom_merge=bottom_merge,
                            init_from=str(onnx_path)), progress=False)


def test_a_fine_tune_of_an_exported_model_carries_its_card(tiny_dataset, tmp_path):
    """The card of a model fine-tuned from an .onnx names the file by digest and appends the base's own card
    (an exported model keeps no history, so its card is the only record of how it was made)."""
    onnx_path = export_onnx(UNet(widths=(4, 8)), tmp_path / "exported.onnx")
    onnx_path.with_suffix(".md").write_text("# exported.onnx — denoiser\n\n## Recipe\n- epochs 7 on seven views\n")
    tuned = Trainer(TrainConfig(task="denoiser", data=str(tiny_dataset), out=str(tmp_path / "out"), epochs=1,
                                batch=2, crop_min=12, crop_max=16, widths=(4, 8), init_from=str(onnx_path)),
                    progress=False)
    tuned.run()
    card = tuned.model_card()
    digest = hashlib.sha256(onnx_path.read_bytes()).hexdigest()[:12]
    assert f"- fine-tuned from the weights of `{onnx_path}` (sha256 {digest}…; its card follows" in card
    base = card[card.index("## Base model"):]
    assert "### Recipe" in base and "- epochs 7 on seven views" in base
    assert "0 epochs, 0.0 min" not in card and "min for the run(s) it was fine-tuned from" not in card


def test_a_nan_loss_stops_training_with_a_clear_message(tiny_dataset, tmp_path, monkeypatch):
    config = TrainConfig(task="denoiser", data=str(tiny_dataset), out=str(tmp_path), epochs=1, batch=2,
                         crop_min=12, crop_max=16, widths=(4, 8))
    trainer = Trainer(config, progress=False)
    monkeypatch.setattr(trainer, "loss", lambda prediction, target, x: (prediction * float("nan")).mean())
    with pytest.raises(TrainingError, match="denoiser: loss became nan at step 0"):
        trainer.run()


def test_a_loss_that_turns_nan_mid_epoch_is_named_by_its_step_and_never_checkpointed(tiny_dataset, tmp_path,
                                                                                     monkeypatch):
    # Losses are read once an epoch (reading each would make the host wait for every step on a GPU), so
    # the message must still name the first bad step, and the epoch's checkpoint must not be written.
    config = TrainConfig(task="denoiser", data=str(tiny_dataset), out=str(tmp_path), epochs=2, batch=2,
                         crop_min=12, crop_max=16, widths=(4, 8))
    trainer = Trainer(config, progress=False)
    real_loss, calls = trainer.loss, []

    def loss_then_nan(prediction, target, x):
        calls.append(1)
        value = real_loss(prediction, target, x)
        return value * float("nan") if len(calls) > trainer.steps_per_epoch + 1 else value

    monkeypatch.setattr(trainer, "loss", loss_then_nan)
    assert trainer.steps_per_epoch >= 3
    with pytest.raises(TrainingError, match=f"loss became nan at step {trainer.steps_per_epoch + 1} \\(epoch 1\\)"):
        trainer.run()
    saved = torch.load(trainer.checkpoint_path, weights_only=False)
    assert saved["epoch"] == 1 and all(torch.isfinite(t).all() for t in saved["model"].values())


def test_confidence_needs_sequences(tmp_path):
    config = DatasetConfig(scenes=("cornell",), views=5, size=8, spp=(1,), gold=4,
                           sequence_fraction=0.0)
    TruthEngine(config, tmp_path / "data", renderer=fake_render).run(progress=False)
    (tmp_path / "out").mkdir()
    export_onnx(UNet(widths=(4, 8)), tmp_path / "out" / "denoiser.onnx")   # the denoiser it learns behind
    with pytest.raises(TrainingError, match="no train samples for confidence.*sequences"):
        Trainer(TrainConfig(task="confidence", data=str(tmp_path / "data"), out=str(tmp_path / "out")),
                progress=False)


def test_a_dataset_too_small_to_hold_back_validation_views_says_how_to_fix_it(tmp_path):
    config = DatasetConfig(scenes=("cornell",), views=2, size=8, spp=(1,), gold=4, sequence_fraction=0.0)
    TruthEngine(config, tmp_path / "data", renderer=fake_render).run(progress=False)
    with pytest.raises(TrainingError, match="no val samples for denoiser .*from 3 of them up: render more"):
        Trainer(TrainConfig(task="denoiser", data=str(tmp_path / "data"), out=str(tmp_path / "out")), progress=False)


def test_denoiser_batches_draw_every_noisy_copy_at_1_spp_only(tmp_path):
    from wgpu_rt.dataset import load_views
    from wgpu_rt.frame.pack import pack_denoiser_input
    from wgpu_rt.train.samples import Augmentation, DenoiserSamples

    config = DatasetConfig(scenes=("cornell",), views=3, size=16, spp=(1, 4), gold=8, sequence_fraction=0.0,
                           noisy_copies=3)
    TruthEngine(config, tmp_path, renderer=fake_render).run(progress=False)
    samples = DenoiserSamples(load_views(tmp_path, "train"))
    item = samples.items[0]
    assert samples.copies(item, 1) == 3 and samples.copies(item, 4) == 1
    second = samples.views[0].frames[0].copies[0]
    x, _ = samples.full(item, 1, 1.0, copy=1)
    np.testing.assert_allclose(x, pack_denoiser_input(second["color"], second["albedo"], second["normal"],
                                                      second["depth"]), rtol=1e-6)
    drawn = []
    planes = samples.planes
    samples.planes = lambda item, spp, copy=0: drawn.append((spp, copy)) or planes(item, spp, copy)
    rng = np.random.default_rng(0)
    for spp in (1, 4):
        for _ in range(30):
            samples.batch([item], rng, Augmentation(8, 16), spp)
    assert {c for s, c in drawn if s == 1} == {0, 1, 2} and {c for s, c in drawn if s == 4} == {0}
    drawn.clear()
    for _ in range(30):
        x, _ = samples.batch([item], rng, Augmentation(8, 16), ANY_SPP)
        assert x[0, -1].unique().tolist() == [1 / drawn[-1][0] ** 0.5]   # the plane says which was drawn
    assert {s for s, _ in drawn} == {1, 4}
    assert "(3 independent renders of each frame at 1 spp)" in Trainer._dataset_line(str(tmp_path))
    card = Trainer(TrainConfig(task="denoiser", data=str(tmp_path), out=str(tmp_path / "m"), widths=(4, 8)),
                   progress=False).model_card()
    assert "each draw takes a random one of a frame's independent 1-spp renders" in card


def test_a_batch_mixing_frame_sizes_crops_to_fit_the_smallest(tmp_path):
    """Datasets rendered at several sizes train together (--extra-data): a batch's one crop size must fit
    every frame in it, not only the first item's (a 192² view first and a 96² one after it failed)."""
    from wgpu_rt.dataset import load_views
    from wgpu_rt.train.samples import Augmentation, DenoiserSamples

    for name, size in (("large", 32), ("small", 16)):
        config = DatasetConfig(scenes=("cornell",), views=2, size=size, spp=(1,), gold=8, sequence_fraction=0.0)
        TruthEngine(config, tmp_path / name, renderer=fake_render).run(progress=False)
    samples = DenoiserSamples(load_views(tmp_path / "large") + load_views(tmp_path / "small"))
    sizes = [view.frames[0].gold["color"].shape[0] for view in samples.views]
    large = next(item for item in samples.items if sizes[item[0]] == 32)
    small = next(item for item in samples.items if sizes[item[0]] == 16)
    rng = np.random.default_rng(0)
    for _ in range(10):
        x, y = samples.batch([large, small], rng, Augmentation(8, 32), 1)
        assert x.shape[-2:] == y.shape[-2:] and 8 <= x.shape[-1] <= 16
    x, _ = samples.batch([large], rng, Augmentation(32, 32), 1)
    assert x.shape[-1] == 32   # alone, the large frame still gives whole-frame crops


def test_batch_wide_turns_flips_and_colour_orders_are_each_crops_own():
    """The batch's gathers do to each crop what its own draw says: transform 2·turns + flip is torch.rot90
    by ``turns`` in the (H, W) plane, then W flipped; a colour order reorders each RGB triple alone."""
    from wgpu_rt.train.samples import RGB_ORDERS, DenoiserSamples, _dihedral, _gather_channels

    batch = torch.randn(8, 7, 6, 6)
    samples = DenoiserSamples([])
    turned = _dihedral(batch, samples._dihedral_maps(6, batch.device), list(range(8)))
    for t in range(8):
        expected = torch.rot90(batch[t], t // 2, dims=(1, 2))
        assert torch.equal(turned[t], expected.flip(2) if t % 2 else expected)
    triples = (slice(0, 3), slice(3, 6))
    reordered = _gather_channels(batch[:6], samples._colour_tables(7, triples, batch.device), list(range(6)))
    for k, order in enumerate(RGB_ORDERS):
        assert torch.equal(reordered[k], batch[k][[*order, *(3 + np.array(order)), 6]])


def test_colour_permutation_reorders_colour_and_albedo_alike(tiny_dataset):
    """With permute_colours a denoiser crop's colour and albedo planes (input) and gold and albedo factor
    (target) are the unpermuted crop's channels in one shared order; normals, depth and spp are kept; the
    order varies between draws (the identity among them)."""
    from wgpu_rt.dataset import load_views
    from wgpu_rt.train.samples import Augmentation, DenoiserSamples

    samples = DenoiserSamples(load_views(tiny_dataset))
    item = samples.items[0]
    orders = set()
    for seed in range(12):
        plain = samples.batch([item], np.random.default_rng(seed), Augmentation(8, 8, aux_noise=0.0), 1)
        permuted = samples.batch([item], np.random.default_rng(seed), Augmentation(8, 8, aux_noise=0.0,
                                                                               permute_colours=True), 1)
        (x, y), (px, py) = ([t[0].numpy() for t in pair] for pair in (plain, permuted))
        order = next(o for o in itertools.permutations(range(3)) if np.array_equal(px[0:3], x[0:3][list(o)]))
        orders.add(order)
        for a, b in ((px[3:6], x[3:6]), (py[0:3], y[0:3]), (py[3:6], y[3:6])):
            np.testing.assert_array_equal(a, b[list(order)])
        np.testing.assert_array_equal(px[6:], x[6:])
    assert len(orders) > 2 and (0, 1, 2) in orders


def test_confidence_needs_the_denoiser_it_learns_on(tiny_dataset, tmp_path):
    with pytest.raises(TrainingError, match=r"denoiser\.onnx: no denoiser"):
        Trainer(TrainConfig(task="confidence", data=str(tiny_dataset), out=str(tmp_path)), progress=False)


def test_confidence_sample_is_the_denoised_frame_against_history(tiny_dataset):
    """Input: the current frame as the temporal pass's source (the denoiser's output, not the 1-spp
    render), reprojected history; target: 1 where the history is valid."""
    from wgpu_rt.dataset import load_views
    from wgpu_rt.frame.pack import CONFIDENCE_KEY, log_color, radiance_exposure
    from wgpu_rt.train.samples import ConfidenceSamples
    from wgpu_rt.train.targets import disocclusion_mask

    denoised = {}

    def stand_in_denoiser(render):
        denoised[id(render)] = np.full_like(render["color"], 0.25 + len(denoised))
        return denoised[id(render)]

    samples = ConfidenceSamples(load_views(tiny_dataset, "train"), stand_in_denoiser, auto_exposure=False)
    view_index, t = samples.items[0]
    frames = samples.views[view_index].frames
    x, target = samples.full((view_index, t), 1, 2.0)
    mask = disocclusion_mask(frames[t].gold["color"], frames[t + 1].gold["color"], frames[t + 1].gold["motion"])
    assert 0 < mask.mean() < 1
    np.testing.assert_array_equal(target[0], 1 - mask)
    source = denoised[id(frames[t + 1].noisy[1])]
    np.testing.assert_allclose(x[:3], log_color(2.0 * source), rtol=1e-6)
    samples.full((view_index, t), 1, 1.0)
    assert len(denoised) == 1   # each pair's frame is denoised once
    # with the exposure step (the default) source and history are read at the source's key
    exposed = ConfidenceSamples(samples.views, lambda render: source)
    scale = np.float32(radiance_exposure(source, CONFIDENCE_KEY))   # then the exposure 2 on top
    assert abs(np.log2(scale)) > 1
    x_exposed, _ = exposed.full((view_index, t), 1, 2.0)
    np.testing.assert_allclose(x_exposed[:3], log_color(2.0 * source / scale), rtol=1e-5)
    np.testing.assert_allclose(np.expm1(x_exposed[3:6]), np.expm1(x[3:6]) / scale, rtol=1e-4, atol=1e-7)
    np.testing.assert_array_equal(x_exposed[6:], x[6:])


def test_onnx_denoiser_is_the_denoise_command_with_the_exported_network(tiny_dataset, tmp_path):
    from wgpu_rt.dataset import load_views
    from wgpu_rt.frame.denoise import denoise
    from wgpu_rt.train.samples import OnnxDenoiser

    torch.manual_seed(3)
    network = UNet(widths=(4, 8)).eval()
    render = load_views(tiny_dataset, "train")[0].frames[0].noisy[1]

    def torch_network(x):
        with torch.no_grad():
            return network(torch.from_numpy(x)).numpy()

    expected = denoise(torch_network, render["color"], render["albedo"], render["normal"], render["depth"])
    denoiser = OnnxDenoiser(export_onnx(network, tmp_path / "denoiser.onnx"))
    np.testing.assert_allclose(denoiser(render), expected, rtol=1e-4, atol=1e-5)
    assert not np.allclose(expected, render["color"], atol=1e-3)   # the network changed the render
    ten_inputs = UNet(in_channels=DENOISER.input_channels - 1, widths=(4, 8)).eval()   # before the spp plane
    np.testing.assert_allclose(OnnxDenoiser(export_onnx(ten_inputs, tmp_path / "ten.onnx"))(render),
                               denoise(lambda x: ten_inputs(torch.from_numpy(x[:, :-1])).detach().numpy(),
                                       render["color"], render["albedo"], render["normal"], render["depth"]),
                               rtol=1e-4, atol=1e-5)


def test_exposure_on_the_packed_planes_equals_packing_the_scaled_render(tiny_dataset):
    """Samples expose the kept log1p planes (log1p(e · expm1(p))): the same as packing the render scaled
    by e with the frame's own gains, as the numpy references do (gains found anew would take the scale out:
    they carry the frame's exposure); the error predictor's target is ``targets.error_heatmap`` of the
    scaled renders (its percentile depends on the exposure)."""
    from wgpu_rt.dataset import load_views
    from wgpu_rt.frame.pack import (albedo_factor, demodulated_log_color, pack_denoiser_input, pack_error_input,
                                    probe_exposure, white_balance_gains)
    from wgpu_rt.train.samples import DenoiserSamples, ErrorSamples
    from wgpu_rt.train.targets import error_heatmap

    views = load_views(tiny_dataset, "train")
    frame = views[0].frames[0]
    noisy, gold = frame.noisy[4], frame.gold["color"]
    balance = white_balance_gains(noisy["color"], noisy["albedo"])
    x, y = DenoiserSamples(views).full((0, 0), 4, 2.5)
    np.testing.assert_allclose(x, pack_denoiser_input(2.5 * noisy["color"], noisy["albedo"], noisy["normal"],
                                                      noisy["depth"], 4, balance=balance), rtol=2e-6, atol=1e-6)
    np.testing.assert_array_equal(x[-1], 0.5)    # the sample-count plane: 1/sqrt(4)
    np.testing.assert_allclose(y, np.concatenate([demodulated_log_color(2.5 * gold, noisy["albedo"], balance),
                                                  albedo_factor(noisy["albedo"], balance)]), rtol=2e-6, atol=1e-6)
    probe = frame.noisy[1]["color"]
    x, y = ErrorSamples(views, auto_exposure=False).full((0, 0), 1, 0.6)
    np.testing.assert_allclose(x, pack_error_input(0.6 * probe), rtol=2e-6, atol=1e-6)
    np.testing.assert_allclose(y[0], error_heatmap(0.6 * probe, 0.6 * gold), atol=1e-5)
    assert 0 < y.mean() < 1
    scale = probe_exposure(probe) / 0.6                             # the jitter is around the probe's key
    assert abs(np.log2(scale * 0.6)) > 0.5                          # the key moves this frame
    x, y = ErrorSamples(views).full((0, 0), 1, 0.6)
    np.testing.assert_allclose(x, pack_error_input(probe, scale), rtol=2e-6, atol=1e-6)
    np.testing.assert_allclose(y[0], error_heatmap(probe / np.float32(scale), gold / np.float32(scale)), atol=1e-5)


def test_kept_planes_give_the_same_batches_and_are_built_once(tiny_dataset):
    """What the CUDA path does (planes kept on the device) draws exactly the CPU path's batches; the aux
    noise lands on the G-buffer channels only."""
    from wgpu_rt.dataset import load_views
    from wgpu_rt.train.samples import Augmentation, DenoiserSamples

    views = load_views(tiny_dataset, "train")
    packed, kept = DenoiserSamples(views), DenoiserSamples(views)
    kept.keep_on(torch.device("cpu"))
    built = []
    planes = kept.planes
    kept.planes = lambda item, spp, copy=0: built.append((item, spp, copy)) or planes(item, spp, copy)
    items = kept.items[:3]
    for seed in range(3):
        expected = packed.batch(items, np.random.default_rng(seed), Augmentation(8, 16, 2), 4)
        drawn = kept.batch(items, np.random.default_rng(seed), Augmentation(8, 16, 2), 4)
        for a, b in zip(expected, drawn):
            assert torch.equal(a, b)
    assert sorted(built) == sorted((item, 4, 0) for item in items)
    noiseless = kept.batch(items, np.random.default_rng(0), Augmentation(8, 16, 2, aux_noise=0.0), 4)
    noisy = kept.batch(items, np.random.default_rng(0), Augmentation(8, 16, 2), 4)
    noise = (noisy[0] - noiseless[0]).abs().amax(dim=(0, 2, 3))   # per channel
    assert (noise[3:10] > 0).all() and (noise[:3] == 0).all() and torch.equal(noisy[1], noiseless[1])
    assert noise[10] == 0                                          # the sample count is exact


def test_preloaded_planes_are_every_render_packed_once(tiny_dataset):
    """``preload`` packs each noisy render of each view's sample counts up front (the CUDA path), so no
    draw packs again, and draws the same batches as packing at every draw."""
    from wgpu_rt.dataset import load_views
    from wgpu_rt.train.samples import Augmentation, DenoiserSamples

    views = load_views(tiny_dataset, "train")
    packed, kept = DenoiserSamples(views), DenoiserSamples(views)
    kept.keep_on(torch.device("cpu"))
    kept.preload(every_spp=True, workers=2)
    expected_keys = {(item, spp, copy) for item in kept.items for spp in views[item[0]].spp
                     for copy in range(kept.copies(item, spp))}
    assert set(kept._kept) == expected_keys
    kept.planes = lambda *key: pytest.fail(f"{key} packed again")
    for spp in (1, 16):
        expected = packed.batch(kept.items[:4], np.random.default_rng(spp), Augmentation(8, 16, 2), spp)
        for a, b in zip(expected, kept.batch(kept.items[:4], np.random.default_rng(spp), Augmentation(8, 16, 2), spp)):
            assert torch.equal(a, b)


def test_a_kept_budget_keeps_the_first_frames_drawn_and_packs_the_rest_each_time(tiny_dataset):
    """A CPU run keeps packed frames up to its budget in bytes (the first drawn); frames past it are
    packed again at each draw, and the batches are the same either way."""
    from wgpu_rt.dataset import load_views
    from wgpu_rt.train.samples import Augmentation, DenoiserSamples

    views = load_views(tiny_dataset, "train")
    packed, kept = DenoiserSamples(views), DenoiserSamples(views)
    one_frame = sum(a.nbytes for a in packed.planes(packed.items[0], 1))
    kept.keep_on(torch.device("cpu"), budget=2 * one_frame)
    packs = []
    planes = kept.planes
    kept.planes = lambda *key: packs.append(key) or planes(*key)
    for _ in range(2):
        expected = packed.batch(kept.items[:4], np.random.default_rng(3), Augmentation(8, 16, 2), 1)
        for a, b in zip(expected, kept.batch(kept.items[:4], np.random.default_rng(3), Augmentation(8, 16, 2), 1)):
            assert torch.equal(a, b)
    assert len(kept._kept) == 2 and kept._kept_bytes <= 2 * one_frame
    assert len(packs) == 4 + 2, packs     # the first pass packs all four, the second the two not kept


@pytest.mark.parametrize("task", ["denoiser", "error_predictor"])
def test_a_crop_is_exposed_as_the_frame_would_be(tiny_dataset, task):
    """Exposing only the crop (targets made pixel by pixel) gives the crop of the exposed frame; the error
    predictor's target, scaled by a percentile of the whole frame, is cropped after it is made."""
    from wgpu_rt.dataset import load_views
    from wgpu_rt.train.samples import samples_for

    samples = samples_for(task, load_views(tiny_dataset, "train"))
    item = samples.items[0]
    whole = samples.exposed(item, 1, 1.7)
    window = (3, 5, 8)
    for a, b in zip(whole, samples.exposed(item, 1, 1.7, window=window)):
        assert torch.allclose(a[:, 3:11, 5:13], b, rtol=1e-6, atol=1e-6)
    assert samples.pixelwise_target == (task == "denoiser")


def test_a_time_budget_follows_the_pace_after_the_first_epoch(tiny_dataset, tmp_path):
    """The first epoch carries the warm-up: the epochs that fit are judged by the later ones' pace, and
    raised again (up to those asked) when the pace improves."""
    trainer = Trainer(TrainConfig(task="denoiser", data=str(tiny_dataset), epochs=100, widths=(4, 8), batch=2,
                                  crop_min=12, crop_max=16, minutes=1.0, out=str(tmp_path / "m"),
                                  checkpoints=str(tmp_path / "ck")))
    trainer.epoch = 1
    trainer._fit_epochs_to_minutes(20.0, np.array([20.0]))       # a slow first epoch: 40 s left, 2 more
    assert trainer.config.epochs == 3 and trainer.epochs_asked == 100
    trainer.epoch = 2
    trainer._fit_epochs_to_minutes(21.0, np.array([20.0, 1.0]))  # at 1 s an epoch, 39 more
    assert trainer.config.epochs == 41 and trainer.total_steps == 41 * trainer.steps_per_epoch
    trainer._fit_epochs_to_minutes(21.0, np.array([20.0, 0.1]))  # more than asked would fit
    assert trainer.config.epochs == 100 and trainer.epochs_asked is None


def test_ranks_train_on_disjoint_equal_shares_of_each_epoch():
    from wgpu_rt.train.context import TrainContext

    order = np.random.default_rng(0).permutation(10)
    shares = [TrainContext(torch.device("cpu"), rank, 3).shard(order) for rank in range(3)]
    assert [len(s) for s in shares] == [4, 4, 4]
    assert sorted(np.concatenate(shares)) == sorted([*range(10), *order[:2]])   # two drawn twice, to even out
    assert TrainContext(torch.device("cpu")).shard(order) is order


@pytest.mark.parametrize("seconds, saved_after", [(1e9, [1, 4]), (0.0, [1, 2, 3, 4])])
def test_checkpoints_after_the_first_epoch_the_last_and_once_a_while(tiny_dataset, tmp_path, monkeypatch,
                                                                     seconds, saved_after):
    """A checkpoint at the end of a session's first epoch, of the run's last, and between them once
    CHECKPOINT_SECONDS have passed since the last (short CUDA epochs spent a share of the run writing one
    at each end)."""
    from wgpu_rt.train import trainer as trainer_module

    monkeypatch.setattr(trainer_module, "CHECKPOINT_SECONDS", seconds)
    trainer = Trainer(TrainConfig(task="error-predictor", data=str(tiny_dataset), out=str(tmp_path), epochs=4,
                                  batch=2, crop_min=8, crop_max=16), progress=False)
    saved, save = [], trainer._save_checkpoint
    monkeypatch.setattr(trainer, "_save_checkpoint", lambda: saved.append(trainer.epoch) or save())
    trainer.run()
    assert saved == saved_after
    assert torch.load(trainer.checkpoint_path, weights_only=False)["epoch"] == 4


def test_a_resumed_run_ends_where_the_uninterrupted_one_does(tiny_dataset, tmp_path):
    base = dict(task="denoiser", data=str(tiny_dataset), batch=2, crop_min=12, crop_max=16, widths=(4, 8),
                device="cpu")
    whole = Trainer(TrainConfig(epochs=2, out=str(tmp_path / "whole"), **base), progress=False)
    whole.run()
    interrupted = Trainer(TrainConfig(epochs=2, out=str(tmp_path / "split"), **base), progress=False)
    save = interrupted._save_checkpoint

    def save_then_get_killed():
        save()
        raise KeyboardInterrupt

    interrupted._save_checkpoint = save_then_get_killed   # stops after epoch 1's checkpoint
    with pytest.raises(KeyboardInterrupt):
        interrupted.run()
    # --device may change on resume; "auto" is the CPU unless torch sees CUDA, where the second epoch would
    # train on another device and not end bit for bit where the CPU run did
    other_spelling = "cpu" if torch.cuda.is_available() else "auto"
    resumed = Trainer(TrainConfig(epochs=2, out=str(tmp_path / "split"), resume=True,
                                  **{**base, "device": other_spelling}), progress=False)
    assert resumed.epoch == 1
    resumed.run()
    for name, weight in whole.model.state_dict().items():
        assert torch.equal(resumed.model.state_dict()[name], weight), name


@pytest.mark.parametrize("amp_dtype", [torch.bfloat16, torch.float16])
def test_the_gpu_recipe_trains_and_resumes_a_cpu_checkpoint(amp_dtype, tiny_dataset, tmp_path):
    """The CUDA path's recipe (planes kept on the device, autocast, a GradScaler for float16, channels-last
    weights and batches) run on the CPU, which torch allows: it resumes a plain CPU run's checkpoint and
    its own, with finite losses, and exports the same network as ONNX."""
    from wgpu_rt.train.context import TrainContext

    base = dict(task="denoiser", data=str(tiny_dataset), out=str(tmp_path), batch=2, crop_min=12, crop_max=16,
                widths=(4, 8))
    Trainer(TrainConfig(epochs=1, device="cpu", **base), progress=False).run()
    gpu_like = TrainContext(torch.device("cpu"), amp_dtype=amp_dtype, keep_data=True,
                            memory_format=torch.channels_last)
    resumed = Trainer(TrainConfig(epochs=2, resume=True, **base), progress=False, context=gpu_like)
    assert resumed.epoch == 1 and resumed.train_set._kept == {}
    resumed.run()
    assert resumed.epoch == 2 and np.isfinite(resumed.history[-1]["train_loss"]) and resumed.train_set._kept
    assert resumed.model.down[0][0].weight.is_contiguous(memory_format=torch.channels_last)
    import onnxruntime as ort

    onnx_path, _ = resumed.export()
    x = np.random.default_rng(0).uniform(0, 1, (1, 11, 16, 16)).astype(np.float32)
    session = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
    with torch.no_grad():
        expected = resumed.model.float()(torch.from_numpy(x)).numpy()
    np.testing.assert_allclose(session.run(None, {session.get_inputs()[0].name: x})[0], expected, atol=1e-4)
    saved = torch.load(resumed.checkpoint_path, weights_only=False)
    assert bool(saved["scaler"]) == (amp_dtype == torch.float16)
    again = TrainContext(torch.device("cpu"), amp_dtype=amp_dtype, keep_data=True)
    assert Trainer(TrainConfig(epochs=3, resume=True, **base), progress=False, context=again).epoch == 2
    if amp_dtype == torch.float16:
        assert again.scaler.get_scale() == saved["scaler"]["scale"]


def test_throughput_is_printed_and_on_the_card(tiny_dataset, tmp_path, capsys):
    from wgpu_rt.cli import main

    out = tmp_path / "models"
    assert main(["train", "error-predictor", "--data", str(tiny_dataset), "--out", str(out), "--epochs", "2",
                 "--batch", "2", "--crop", "8", "16", "--quiet"]) == 0
    summary = capsys.readouterr().out
    assert "steps_per_s " in summary and "views_per_hour " in summary
    card = (out / "error_predictor.md").read_text()
    speed = [line for line in card.splitlines() if line.startswith("- throughput: ")]
    assert len(speed) == 1 and "steps/s" in speed[0] and "training views/hour (batch 2 × 1 process(es)" in speed[0]


def world_view(number: int) -> dict:
    """A manifest's record of a generated world's 32², 1-spp view."""
    return {"view_id": f"v{number:05d}", "scene": f"world-{100 + number}", "split": "train", "frames": 1,
            "size": 32, "spp": [1], "gold": 64, "objects": [], "seconds": 1.0}


def test_the_card_names_a_worlds_dataset_by_its_family(tmp_path):
    (tmp_path / "manifest.json").write_text(json.dumps({"config": {
        "worlds": 3, "family": "held_out", "scenes": [], "size": 32, "spp": [1], "gold": 64, "seed": 5,
        "max_depth": 8}, "views": [world_view(n) for n in range(3)]}))
    line = Trainer._dataset_line(str(tmp_path))
    assert "adapter: 3 generated worlds of the held_out family; 32² px" in line


def test_the_card_of_a_stopped_worlds_render_says_how_many_worlds_it_holds(tmp_path):
    (tmp_path / "manifest.json").write_text(json.dumps({"config": {
        "worlds": 150, "family": "training", "scenes": [], "size": 32, "spp": [1], "gold": 64, "seed": 5,
        "max_depth": 8}, "views": [world_view(n) for n in range(2)]}))
    line = Trainer._dataset_line(str(tmp_path))
    assert "adapter: 2 of 150 generated worlds of the training family;" in line and "2 views rendered" in line


UNTINTED = "the albedo through mirrors and glass untinted by their colour"


@pytest.mark.parametrize("version, words", [
    (1, "escaping paths with albedo 0; emitters with their reflectance as albedo, 0 for a black lamp; "
        f"{UNTINTED} (rendered before the guide albedo's version 2)"),
    (2, f"emitters with their reflectance as albedo, 0 for a black lamp; {UNTINTED} (rendered before the guide "
        "albedo's version 3)"),
    (3, f"{UNTINTED} (rendered before the guide albedo's version 4)"),
])
def test_the_card_says_which_albedo_an_older_dataset_holds(tiny_dataset, tmp_path, version, words):
    """A dataset rendered under an older guide albedo (its manifest's ``guide_albedo``, 1 where absent) is
    named with what its albedo planes held; one rendered today, with nothing."""
    import json
    import shutil

    base = dict(task="denoiser", out=str(tmp_path / "out"), widths=(4, 8))
    assert "rendered before the guide albedo" not in Trainer(TrainConfig(data=str(tiny_dataset), **base),
                                                             progress=False).model_card()
    older = tmp_path / "older"
    shutil.copytree(tiny_dataset, older)
    manifest = json.loads((older / "manifest.json").read_text())
    manifest["config"]["guide_albedo"] = version
    (older / "manifest.json").write_text(json.dumps(manifest))
    assert words in Trainer(TrainConfig(data=str(older), **base), progress=False).model_card()
