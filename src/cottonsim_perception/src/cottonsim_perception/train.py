"""Train a Cotton-Eye network (scene segmenter or boll detector) on the CPU.

Why this shape: the datasets are small (173 segmentation / 26 detection
training images), so training is a plain single-process loop: AdamW with a
linear warm-up and a cosine decay, an exponential moving average (EMA) of the
weights (what gets saved and used, as in YOLOv8), the data loader of
:mod:`cottonsim_perception.data.yolo_dataset` with flip / HSV / scale /
translate (and optional rotation) augmentation.

Reproducible and resumable: everything random is seeded from ``seed`` (the
augmentation of item i in epoch e is a function of (seed, e, i), the shuffle
order of epoch e of (seed, e)), and ``out/last.pt`` is written after every
epoch with the optimizer state, the raw weights and the EMA weights, so
``resume`` continues exactly where it stopped. ``out/best.pt`` is the epoch
with the lowest validation loss (EMA weights, eval-mode BatchNorm, no
augmentation).
"""
from __future__ import annotations

import copy
import math
import os
import time
from dataclasses import dataclass, replace
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np
import torch
from torch.utils.data import DataLoader

from .nn.heads import PROTO_STRIDES
from .nn.loss import LossConfig, YoloLoss
from .nn.models import ModelConfig, YoloModel, build_model, load_checkpoint, save_checkpoint


def parse_imgsz(text: str) -> Tuple[int, int]:
    """'WxH' or 'W' (height = 3/4 W rounded to 32) -> (width, height) [px], multiples of 32."""
    text = str(text).lower().strip()
    try:
        if "x" in text:
            w, h = (int(v) for v in text.split("x"))
        else:
            w = int(text)
            h = max(32, int(round(w * 0.75 / 32.0)) * 32)
    except ValueError as exc:
        raise ValueError(f"imgsz must be 'W' or 'WxH' in px, got {text!r}") from exc
    if w < 32 or h < 32 or w % 32 or h % 32:
        raise ValueError(f"imgsz sides must be positive multiples of 32 px, got {w}x{h}")
    return w, h


@dataclass(frozen=True)
class TrainConfig:
    """One training run.

    task: 'seg' or 'det'; data_dir: YOLO dataset root ({train,valid}/{images,labels});
    out_dir: where last.pt / best.pt go; epochs: total epochs; batch: images
    per step; imgsz: (width, height) network input [px] or None for the
    task's default (seg 320x256, det 640x480); width_multiple: None for the
    task's default; seed: RNG seed; threads: torch CPU threads; lr: peak
    AdamW learning rate; weight_decay: on conv / linear weights only;
    warmup_iters: linear LR warm-up steps; final_lr_fraction: cosine floor
    as a fraction of lr; ema_decay / ema_tau: EMA decay d * (1 - exp(-updates / tau));
    rotation_deg: +/- rotation augmentation (0 = off); max_minutes: stop
    (after saving) when the wall time exceeds this (None = no limit);
    resume: a last.pt to continue from; init_weights: a checkpoint (e.g. the
    shipped weights) whose weights start the run (fine-tuning; its model
    configuration must equal this run's; ignored when resuming);
    extra_data_dirs: more YOLO dataset roots whose train and valid splits are
    added to data_dir's (e.g. the paper's images + simulator images; the
    class names must agree; a root without a valid split adds training
    images only); mosaic_prob: probability that a training item is
    a 2x2 mosaic of four images (YOLOv8's mosaic, see YoloDataset; 0 = off);
    proto_stride: segmenter prototype stride (4, 2 or 1 input px; None = the
    preset's 4; 1 adds the full-resolution detail path, see heads.Proto); device: torch device to train on ('cpu', 'cuda', 'cuda:1';
    checkpoints are always written as CPU tensors); workers: DataLoader
    worker processes (0 = load in the training process; the augmentation of
    item i in epoch e is the same either way, see YoloDataset);
    mask_dice_weight: weight of the soft Dice term added to the segmenter's
    mask BCE (``nn.loss.LossConfig``; 0 = BCE only, as YOLOv8).
    init_weights of the same network with another proto_stride is accepted:
    every tensor whose name and shape match is loaded, the new Proto layers
    start from their random initialisation (logged).
    """

    task: str
    data_dir: str
    out_dir: str
    epochs: int = 100
    batch: int = 8
    imgsz: Optional[Tuple[int, int]] = None
    width_multiple: Optional[float] = None
    seed: int = 0
    threads: int = 1
    lr: float = 2e-3
    weight_decay: float = 5e-4
    warmup_iters: int = 100
    final_lr_fraction: float = 0.01
    ema_decay: float = 0.9999
    ema_tau: float = 2000.0
    rotation_deg: float = 0.0
    max_minutes: Optional[float] = None
    resume: Optional[str] = None
    init_weights: Optional[str] = None
    extra_data_dirs: Tuple[str, ...] = ()
    mosaic_prob: float = 0.0
    proto_stride: Optional[int] = None
    device: str = "cpu"
    workers: int = 0
    mask_dice_weight: float = 0.0

    def __post_init__(self) -> None:
        if self.task not in ("seg", "det"):
            raise ValueError(f"TrainConfig.task must be 'seg' or 'det', got {self.task!r}")
        if not os.path.isdir(self.data_dir):
            raise ValueError(f"TrainConfig.data_dir is not a folder: {self.data_dir!r}")
        for name in ("epochs", "batch", "threads"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise ValueError(f"TrainConfig.{name} must be a positive int, got {v!r}")
        if not isinstance(self.warmup_iters, int) or self.warmup_iters < 0:
            raise ValueError(f"TrainConfig.warmup_iters must be an int >= 0, got {self.warmup_iters!r}")
        if self.imgsz is not None:
            object.__setattr__(self, "imgsz", parse_imgsz(f"{self.imgsz[0]}x{self.imgsz[1]}"))
        if self.width_multiple is not None and not 0 < self.width_multiple <= 2:
            raise ValueError(f"TrainConfig.width_multiple must be in (0, 2], got {self.width_multiple}")
        if not self.lr > 0:
            raise ValueError(f"TrainConfig.lr must be > 0, got {self.lr}")
        if self.weight_decay < 0:
            raise ValueError(f"TrainConfig.weight_decay must be >= 0, got {self.weight_decay}")
        if not 0 <= self.final_lr_fraction <= 1:
            raise ValueError(f"TrainConfig.final_lr_fraction must be in [0, 1], got {self.final_lr_fraction}")
        if not 0 <= self.ema_decay < 1:
            raise ValueError(f"TrainConfig.ema_decay must be in [0, 1), got {self.ema_decay}")
        if not self.ema_tau > 0:
            raise ValueError(f"TrainConfig.ema_tau must be > 0, got {self.ema_tau}")
        if not 0 <= self.rotation_deg <= 180:
            raise ValueError(f"TrainConfig.rotation_deg must be in [0, 180], got {self.rotation_deg}")
        if self.max_minutes is not None and not self.max_minutes > 0:
            raise ValueError(f"TrainConfig.max_minutes must be > 0 or None, got {self.max_minutes}")
        if self.resume is not None and not os.path.isfile(self.resume):
            raise ValueError(f"TrainConfig.resume: checkpoint not found: {self.resume!r}")
        if self.init_weights is not None and not os.path.isfile(self.init_weights):
            raise ValueError(f"TrainConfig.init_weights: checkpoint not found: {self.init_weights!r}")
        object.__setattr__(self, "extra_data_dirs", tuple(self.extra_data_dirs))
        for d in self.extra_data_dirs:
            if not os.path.isdir(d):
                raise ValueError(f"TrainConfig.extra_data_dirs: not a folder: {d!r}")
        if self.proto_stride is not None and (self.task != "seg" or self.proto_stride not in PROTO_STRIDES):
            raise ValueError(f"TrainConfig.proto_stride must be None, or one of {PROTO_STRIDES} for task 'seg', "
                             f"got {self.proto_stride!r} for task {self.task!r}")
        if not isinstance(self.workers, int) or self.workers < 0:
            raise ValueError(f"TrainConfig.workers must be an int >= 0, got {self.workers!r}")
        try:
            dev = torch.device(self.device)
        except (RuntimeError, TypeError) as exc:
            raise ValueError(f"TrainConfig.device is not a torch device: {self.device!r}") from exc
        if dev.type == "cuda" and not torch.cuda.is_available():
            raise ValueError(f"TrainConfig.device {self.device!r}: this torch has no CUDA device")
        if not (isinstance(self.mosaic_prob, (int, float)) and 0.0 <= self.mosaic_prob <= 1.0):
            raise ValueError(f"TrainConfig.mosaic_prob must be in [0, 1], got {self.mosaic_prob!r}")
        LossConfig(mask_dice_weight=self.mask_dice_weight)      # range check with the loss's own message
        if self.mask_dice_weight != 0.0 and self.task != "seg":
            raise ValueError(f"TrainConfig.mask_dice_weight is for task 'seg' only, got {self.mask_dice_weight!r} "
                             f"for task {self.task!r}")


class ModelEMA:
    """Exponential moving average of a model's parameters and buffers."""

    def __init__(self, model: torch.nn.Module, decay: float, tau: float, updates: int = 0):
        self.ema = copy.deepcopy(model).eval()
        for p in self.ema.parameters():
            p.requires_grad_(False)
        self.decay, self.tau, self.updates = decay, tau, updates

    @torch.no_grad()
    def update(self, model: torch.nn.Module) -> None:
        self.updates += 1
        d = self.decay * (1.0 - math.exp(-self.updates / self.tau))
        msd = model.state_dict()
        for k, v in self.ema.state_dict().items():
            if v.dtype.is_floating_point:
                v.mul_(d).add_(msd[k].detach(), alpha=1.0 - d)
            else:
                v.copy_(msd[k])


def _datasets(cfg: TrainConfig, width: int, height: int, dataset_cls, log: Callable[[str], None] = print):
    """(train set, val set, class names) over data_dir and extra_data_dirs (concatenated).

    data_dir must have a validation split; an extra root without one (or with
    an empty one) adds training images only.
    """
    from torch.utils.data import ConcatDataset

    from .data.yolo_format import class_names_for

    trains, vals, names = [], [], None
    for k, root in enumerate((cfg.data_dir,) + cfg.extra_data_dirs):
        tr = dataset_cls(root, "train", cfg.task, (width, height), augment=True, seed=cfg.seed + 7919 * k,
                         class_names=names)
        if names is None:
            names = tuple(tr.class_names)
        elif tuple(class_names_for(root, cfg.task)) != names:
            raise ValueError(f"{root}: class names {class_names_for(root, cfg.task)} differ from "
                             f"{cfg.data_dir}'s {names}")
        tr.augment_config = type(tr.augment_config)(rotation_deg=cfg.rotation_deg, mosaic_prob=cfg.mosaic_prob)
        if len(tr) == 0:
            raise ValueError(f"{root}: the train split has no images")
        trains.append(tr)
        if k > 0 and not _has_images(root, "valid"):
            log(f"{root}: no validation split, its images only train")
            continue
        vals.append(dataset_cls(root, "valid", cfg.task, (width, height), augment=False, seed=cfg.seed,
                                class_names=names))
    train_set = trains[0] if len(trains) == 1 else _EpochConcat(trains)
    val_set = vals[0] if len(vals) == 1 else ConcatDataset(vals)
    return train_set, val_set, names


def _has_images(root: str, split: str) -> bool:
    """Whether ``root`` has a ``split`` folder holding at least one image."""
    from .data.yolo_format import LabelFormatError, list_pairs

    try:
        return bool(list_pairs(root, split))
    except LabelFormatError:
        return False


class _EpochConcat(torch.utils.data.ConcatDataset):
    """ConcatDataset that forwards set_epoch to its parts."""

    def set_epoch(self, epoch: int) -> None:
        for d in self.datasets:
            d.set_epoch(epoch)


def _param_groups(model: torch.nn.Module, weight_decay: float) -> List[Dict[str, Any]]:
    decay, no_decay = [], []
    for name, p in model.named_parameters():
        (decay if p.ndim > 1 else no_decay).append(p)
    return [{"params": decay, "weight_decay": weight_decay}, {"params": no_decay, "weight_decay": 0.0}]


def _lr_at(cfg: TrainConfig, it: int, total_iters: int) -> float:
    if it < cfg.warmup_iters:
        return cfg.lr * (it + 1) / cfg.warmup_iters
    frac = min(1.0, (it - cfg.warmup_iters) / max(1, total_iters - cfg.warmup_iters))
    floor = cfg.lr * cfg.final_lr_fraction
    return floor + (cfg.lr - floor) * 0.5 * (1.0 + math.cos(math.pi * frac))


def init_from_checkpoint(model: YoloModel, path: str) -> str:
    """Load a checkpoint's weights into ``model`` (fine-tuning start); returns a log line.

    The checkpoint's model configuration must equal ``model.config``, except
    for the input size (a fully convolutional network's weights do not depend
    on it: fine-tuning at another ``imgsz`` starts from the same tensors) and
    a segmenter's proto_stride (and detail_channels): then every tensor whose name
    and shape match is loaded and the other Proto layers keep their own
    initialisation, which for a finer stride is the identity (nearest-
    neighbour copy, zero detail): the finer network starts with the coarse
    one's masks, upsampled. Raises ValueError otherwise.
    """
    init = load_checkpoint(path)
    init_cfg = ModelConfig.from_dict(init["model_config"])
    size = (model.config.input_width, model.config.input_height)
    resized = ""
    if (init_cfg.input_width, init_cfg.input_height) != size:
        resized = f" (trained at input {init_cfg.input_width}x{init_cfg.input_height}, now {size[0]}x{size[1]})"
        init_cfg = replace(init_cfg, input_width=size[0], input_height=size[1])
    if init_cfg == model.config:
        model.load_state_dict(init["state_dict"])
        return f"initialised from {path}{resized}"
    if replace(init_cfg, proto_stride=model.config.proto_stride,
               detail_channels=model.config.detail_channels) == model.config:
        own = model.state_dict()
        loaded = {k: v for k, v in init["state_dict"].items() if k in own and own[k].shape == v.shape}
        model.load_state_dict(loaded, strict=False)
        fresh = sorted(k for k in own if k not in loaded)
        return (f"initialised from {path}{resized} (proto_stride {init_cfg.proto_stride} -> "
                f"{model.config.proto_stride}): {len(loaded)} tensors loaded, {len(fresh)} new: {fresh}")
    raise ValueError(f"{path}: its model_config differs from this run's "
                     f"(task / width / classes must match to fine-tune; the input size may differ)")


def _single_threaded_worker(_worker_id: int) -> None:
    """DataLoader worker set-up: one thread each for torch and OpenCV.

    Every worker would otherwise start a thread pool per library as wide as the
    machine (seen on a 16-core GPU machine: load average 80 with 25 workers).
    """
    import cv2

    torch.set_num_threads(1)
    cv2.setNumThreads(1)


def _to_loss_targets(targets: Dict[str, Any],
                     device: torch.device = torch.device("cpu")) -> Dict[str, torch.Tensor]:
    """The loss's inputs of a collated batch, on ``device``."""
    out = {k: targets[k] for k in ("batch_idx", "classes", "boxes_xyxy")}
    for k in ("masks", "ignore_batch_idx", "ignore_boxes_xyxy"):
        if k in targets:
            out[k] = targets[k]
    return {k: v.to(device, non_blocking=True) for k, v in out.items()}


@torch.no_grad()
def validation_loss(model: YoloModel, loader: DataLoader, loss_fn: YoloLoss) -> float:
    """Mean loss over a loader with eval-mode BatchNorm (no augmentation)."""
    model.eval()
    device = next(model.parameters()).device
    total, n = 0.0, 0
    for images, targets in loader:
        loss, _ = loss_fn(model.raw(images.to(device, non_blocking=True)), _to_loss_targets(targets, device))
        total += float(loss) * images.shape[0]
        n += images.shape[0]
    return total / max(n, 1)


def train(cfg: TrainConfig, log: Callable[[str], None] = print) -> Dict[str, Any]:
    """Run the training described by ``cfg``; returns the final metadata dict.

    Writes ``cfg.out_dir/last.pt`` every epoch and ``best.pt`` on a new best
    validation loss (both EMA weights, loadable with ``load_model``).
    """
    from .data.yolo_dataset import YoloDataset, collate  # the data engineer's loader

    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    device = torch.device(cfg.device)
    if device.type == "cuda":
        torch.backends.cudnn.benchmark = True      # fixed input sizes: let cuDNN pick its kernels
    np.random.seed(cfg.seed)
    preset = ModelConfig.scene_segmenter() if cfg.task == "seg" else ModelConfig.boll_detector()
    width, height = cfg.imgsz if cfg.imgsz is not None else (preset.input_width, preset.input_height)

    train_set, val_set, names = _datasets(cfg, width, height, YoloDataset, log)
    overrides = dict(num_classes=len(names), class_names=names, input_width=width, input_height=height)
    if cfg.width_multiple is not None:
        overrides["width_multiple"] = cfg.width_multiple
    if cfg.proto_stride is not None:
        overrides["proto_stride"] = cfg.proto_stride
    model_cfg = ModelConfig.scene_segmenter(**overrides) if cfg.task == "seg" else \
        ModelConfig.boll_detector(**overrides)

    model = build_model(model_cfg)
    if cfg.init_weights and not cfg.resume:
        log(init_from_checkpoint(model, cfg.init_weights))
    model.to(device)
    optimizer = torch.optim.AdamW(_param_groups(model, cfg.weight_decay), lr=cfg.lr, betas=(0.9, 0.999))
    ema = ModelEMA(model, cfg.ema_decay, cfg.ema_tau)
    loss_fn = YoloLoss(model_cfg.num_classes, model_cfg.reg_max, model.strides,
                       LossConfig(mask_dice_weight=cfg.mask_dice_weight))
    history: Dict[str, List[float]] = {"train_loss": [], "val_loss": []}
    start_epoch, best_val = 0, float("inf")

    if cfg.resume:
        ckpt = load_checkpoint(cfg.resume)
        if ModelConfig.from_dict(ckpt["model_config"]) != model_cfg:
            raise ValueError(f"{cfg.resume}: its model_config differs from this run's "
                             f"(task / imgsz / width / classes must match to resume)")
        state = ckpt.get("optimizer")
        if not isinstance(state, dict) or "model" not in state:
            raise ValueError(f"{cfg.resume}: no optimizer state to resume from (use a last.pt)")
        model.load_state_dict(state["model"])
        optimizer.load_state_dict(state["optimizer"])      # moves its state to the parameters' device
        ema.ema.load_state_dict(ckpt["state_dict"])
        ema.updates = int(state["ema_updates"])
        meta = ckpt["train"]
        start_epoch = int(meta["epochs_done"])
        best_val = float(meta.get("best_val_loss", float("inf")))
        history = {k: list(v) for k, v in meta.get("metrics", history).items()}
        log(f"resumed from {cfg.resume} after epoch {start_epoch}")

    iters_per_epoch = math.ceil(len(train_set) / cfg.batch)
    total_iters = cfg.epochs * iters_per_epoch
    # workers are spawned, not forked: a fork of a process whose OpenMP / numba thread pools are
    # running (a test session, a node) can deadlock in the child (seen in CI)
    loader_options = dict(collate_fn=collate, num_workers=cfg.workers, pin_memory=device.type == "cuda",
                          worker_init_fn=_single_threaded_worker if cfg.workers else None,
                          multiprocessing_context="spawn" if cfg.workers else None)
    val_loader = DataLoader(val_set, batch_size=cfg.batch, shuffle=False, **loader_options)
    t_start = time.time()
    meta: Dict[str, Any] = {}
    for epoch in range(start_epoch, cfg.epochs):
        train_set.set_epoch(epoch)
        gen = torch.Generator().manual_seed(cfg.seed * 100003 + epoch)
        loader = DataLoader(train_set, batch_size=cfg.batch, shuffle=True, generator=gen, **loader_options)
        model.train()
        running, seen = 0.0, 0
        for i, (images, targets) in enumerate(loader):
            it = epoch * iters_per_epoch + i
            for g in optimizer.param_groups:
                g["lr"] = _lr_at(cfg, it, total_iters)
            images = images.to(device, non_blocking=True)
            loss, parts = loss_fn(model(images), _to_loss_targets(targets, device))
            if not torch.isfinite(loss):
                raise RuntimeError(f"loss became {float(loss)} at epoch {epoch + 1} step {i}: lower lr")
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), max_norm=10.0)
            optimizer.step()
            ema.update(model)
            running += float(loss.detach()) * images.shape[0]
            seen += images.shape[0]
        train_loss = running / max(seen, 1)
        val_loss = validation_loss(ema.ema, val_loader, loss_fn) if len(val_set) else float("nan")
        history["train_loss"].append(round(train_loss, 5))
        history["val_loss"].append(round(val_loss, 5))
        elapsed_min = (time.time() - t_start) / 60.0
        log(f"epoch {epoch + 1}/{cfg.epochs} train_loss {train_loss:.4f} val_loss {val_loss:.4f} "
            f"({elapsed_min:.1f} min)")
        improved = val_loss < best_val if math.isfinite(val_loss) else True
        best_val = val_loss if improved and math.isfinite(val_loss) else best_val
        meta = {"task": cfg.task, "data": os.path.abspath(cfg.data_dir), "seed": cfg.seed,
                "extra_data": [os.path.abspath(d) for d in cfg.extra_data_dirs],
                "init_weights": cfg.init_weights, "mosaic_prob": cfg.mosaic_prob,
                "epochs_done": epoch + 1, "epochs": cfg.epochs, "batch": cfg.batch, "lr": cfg.lr,
                "imgsz": [width, height], "best_val_loss": best_val, "metrics": history,
                "proto_stride": model_cfg.proto_stride}
        opt_state = {"optimizer": optimizer.state_dict(), "model": model.state_dict(),
                     "ema_updates": ema.updates}
        save_checkpoint(os.path.join(cfg.out_dir, "last.pt"), ema.ema, meta, opt_state)
        if improved:
            save_checkpoint(os.path.join(cfg.out_dir, "best.pt"), ema.ema, meta)
        if cfg.max_minutes is not None and elapsed_min >= cfg.max_minutes:
            log(f"stopping: max_minutes {cfg.max_minutes} reached after epoch {epoch + 1}")
            break
    return meta
