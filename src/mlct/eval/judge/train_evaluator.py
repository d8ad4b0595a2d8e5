"""Train the text-motion matching evaluator (Guo et al. 2022) on a dataset in the standard layout.

Facts from EricGuo5513/text-to-motion (read, not copied):
- Normalization (data/dataset.py MotionDatasetV2 and Text2MotionDataset with is_train): the
  dataset's Mean/Std, with the std of the root (rotation velocity, linear velocity, height) and
  of the foot contacts divided by feat_bias 5; saved as meta/mean.npy, std.npy. These are the
  evaluator's own statistics (train_tex_mot_match.py loads Comp_v6_KLD01/meta for t2m).
- Stage A, movement autoencoder (train_decomp_v3.py, networks/trainers.py DecompTrainerV3,
  options/train_options.py TrainDecompOptions): MovementConvEncoder on the features without the
  4 foot contacts, MovementConvDecoder back to all D features; 40-frame windows (window_size)
  from the train split's motions, batch 128, Adam lr 1e-4 per network, no gradient clipping;
  loss = L1(recon, x) + 0.001 * mean|z| (sparsity) + 0.001 * L1(z[:, 1:], z[:, :-1]) (smooth).
- Stage B, co-embedding (train_tex_mot_match.py, networks/trainers.py TextMotionMatchTrainer,
  TrainTexMotMatchOptions): TextEncoderBiGRUCo and MotionEncoderBiGRUCo trained with Adam lr 1e-4
  each, batch 32, gradients clipped to norm 0.5 per network; the movement encoder comes from
  stage A, stays in eval mode and its output is detached (frozen); the motion encoder reads
  m_lens // unit_length (4) steps; stage A's last weights are used (the decomp run's
  latest.tar). ContrastiveLoss (networks/modules.py, Hadsell et al. 2006),
  margin 10 (negative_margin): mean((1 - y) d^2 + y max(0, margin - d)^2), d =
  F.pairwise_distance; loss = positive pairs (y = 0) + negative pairs (y = 1) made by shifting the
  batch's motion embeddings. GloVe vectors are fixed inputs. The kept checkpoint, finest.tar, is
  the one of lowest validation loss (checked at epoch ends).

Differences from the reference: steps instead of epochs (validation every `val_every` steps and at
the end, when a val split exists; otherwise the last weights are kept); the shift is drawn from
[1, B - 1] (the reference's randint(0, B - 1) can draw 0 and pair each text with its own motion as
a "negative"), and a negative whose caption equals its text's caption is skipped (the negative
term is the mean over the kept pairs). Without GloVe files, word vectors are learned (see
mlct.eval.judge.learned_words). Network sizes can be reduced (`EvaluatorSizes`) for tests.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Iterator, Literal, Sequence

import numpy as np
import torch
from torch import Tensor, nn
from torch.nn import functional as F

from mlct.data.dataset import Text2MotionEvalDataset, collate
from mlct.data.layout import BadFileError, DatasetLayout
from mlct.devices import resolve_device
from mlct.errors import MlctError
from mlct.eval.judge.evaluator import FOOT_CONTACT_DIMS, UNIT_LENGTH, Evaluator
from mlct.eval.judge.evaluator_dir import (
    GLOVE_PREFIX,
    EvaluatorSizes,
    build_networks,
    load_evaluator_dir,
    prepare_target,
    write_evaluator_dir,
)
from mlct.eval.judge.learned_words import LearnedWordVectors, build_vocabulary
from mlct.eval.judge.networks import LEAK
from mlct.eval.judge.word_vectors import WORD_DIM, WordVectorizer
from mlct.motion.skeleton import Skeleton

__all__ = [  # load_evaluator_dir is re-exported: what train_evaluator writes, it reads
    "EvaluatorTrainConfig", "MovementConvDecoder", "contrastive_loss", "evaluator_mean_std",
    "load_evaluator_dir", "matching_loss", "train_evaluator",
]

DECOMP_FILE = "decomp.tar"  # stage A: 'movement_enc', 'movement_dec', as the reference's
FEAT_BIAS_GROUPS = ("root_rot_velocity", "root_linear_velocity", "root_height", "foot_contact")


@dataclass(frozen=True)
class EvaluatorTrainConfig:
    """Hyperparameters of both stages; defaults from the reference's options/train_options.py."""

    sizes: EvaluatorSizes = field(default_factory=EvaluatorSizes)
    feat_bias: float = 5.0  # root and foot-contact std divided by it (the evaluator's Std)
    decomp_batch_size: int = 128  # TrainDecompOptions.batch_size
    decomp_lr: float = 1e-4
    window_size: int = 40  # frames per stage-A window
    lambda_sparsity: float = 0.001
    lambda_smooth: float = 0.001
    match_lr: float = 1e-4  # TrainTexMotMatchOptions.lr (text, motion and learned word vectors)
    margin: float = 10.0  # negative_margin of the contrastive loss
    clip_norm: float = 0.5  # per network, stage B only
    val_every: int = 500  # steps between validation losses; the lowest one's weights are kept


def _init_weight(module: nn.Module) -> None:
    """Xavier-normal weights, zero biases (the reference's init_weight covers ConvTranspose1d)."""
    if isinstance(module, (nn.ConvTranspose1d, nn.Linear)):
        nn.init.xavier_normal_(module.weight)
        if module.bias is not None:
            nn.init.zeros_(module.bias)


class MovementConvDecoder(nn.Module):
    """Movement codes (B, T', latent) -> features (B, 4 T', D); the reference's layout."""

    def __init__(self, input_size: int, hidden_size: int, output_size: int) -> None:
        super().__init__()
        self.main = nn.Sequential(
            nn.ConvTranspose1d(input_size, hidden_size, 4, 2, 1),
            nn.LeakyReLU(LEAK),
            nn.ConvTranspose1d(hidden_size, output_size, 4, 2, 1),
            nn.LeakyReLU(LEAK),
        )
        self.out_net = nn.Linear(output_size, output_size)
        self.main.apply(_init_weight)
        self.out_net.apply(_init_weight)

    def forward(self, inputs: Tensor) -> Tensor:
        return self.out_net(self.main(inputs.permute(0, 2, 1)).permute(0, 2, 1))


def evaluator_mean_std(mean: np.ndarray, std: np.ndarray, skeleton: Skeleton,
                       feat_bias: float) -> tuple[np.ndarray, np.ndarray]:
    """The evaluator's statistics: the dataset's, root and foot-contact std / feat_bias."""
    std = np.array(std, dtype=np.float32)
    groups = skeleton.layout.groups
    for name in FEAT_BIAS_GROUPS:
        std[groups[name]] /= feat_bias
    return np.array(mean, dtype=np.float32), std


def contrastive_loss(a: Tensor, b: Tensor, negative: bool, margin: float) -> Tensor:
    """Per-pair terms (B,): d^2 for positives, max(0, margin - d)^2 for negatives."""
    distance = F.pairwise_distance(a, b)  # ||a - b + 1e-6||, as the reference
    if negative:
        return torch.clamp(margin - distance, min=0.0).pow(2)
    return distance.pow(2)


def matching_loss(text_emb: Tensor, motion_emb: Tensor, captions: Sequence[str], shift: int,
                  margin: float) -> tuple[Tensor, Tensor]:
    """(positive, negative) mean losses; negatives pair text i with motion i + shift (mod B),
    skipping pairs whose captions are equal."""
    batch = len(text_emb)
    loss_pos = contrastive_loss(text_emb, motion_emb, False, margin).mean()
    partner = (torch.arange(batch) + shift) % batch  # text i meets motion i + shift
    keep = torch.tensor([captions[i] != captions[j] for i, j in enumerate(partner.tolist())],
                        device=text_emb.device)
    terms = contrastive_loss(text_emb, motion_emb[partner.to(text_emb.device)], True, margin)
    loss_neg = terms[keep].mean() if bool(keep.any()) else terms.sum() * 0.0
    return loss_pos, loss_neg


def _generator(seed: int, stream: int) -> torch.Generator:
    """An independent generator per purpose: changing one use of randomness moves no other."""
    state = int(np.random.SeedSequence([seed, stream]).generate_state(1)[0])
    return torch.Generator().manual_seed(state)


class _Windows:
    """Stage A's windows: uniform over every `window`-frame window of the motions."""

    def __init__(self, motions: list[np.ndarray], window: int) -> None:
        self.motions = [torch.from_numpy(m) for m in motions if len(m) >= window]
        if not self.motions:
            raise MlctError(f"no train motion has the {window} frames of a stage-A window")
        counts = torch.tensor([len(m) - window + 1 for m in self.motions])
        self.starts = torch.cumsum(counts, 0) - counts  # first window index of each motion
        self.total = int(counts.sum())
        self.window = window

    def batch(self, size: int, generator: torch.Generator) -> Tensor:
        picks = torch.randint(0, self.total, (size,), generator=generator)
        owner = torch.searchsorted(self.starts, picks, right=True) - 1
        offsets = picks - self.starts[owner]
        return torch.stack([self.motions[m][o:o + self.window]
                            for m, o in zip(owner.tolist(), offsets.tolist())])  # (B, W, D)


def _epochs(count: int, batch_size: int, generator: torch.Generator) -> Iterator[list[int]]:
    """Shuffled batches of item indices, epoch after epoch, the last partial one dropped."""
    while True:
        order = torch.randperm(count, generator=generator).tolist()
        for start in range(0, count - batch_size + 1, batch_size):
            yield order[start:start + batch_size]


class _TextInputs:
    """Token lists -> (word vectors (B, L, word), POS one-hots (B, L, 15)) on the device."""

    def __init__(self, vectorizer: WordVectorizer, embedding: nn.Embedding | None,
                 device: torch.device) -> None:
        self.vectorizer, self.embedding, self.device = vectorizer, embedding, device

    def __call__(self, token_lists: Sequence[Sequence[str]]) -> tuple[Tensor, Tensor]:
        if self.embedding is None:  # GloVe: fixed vectors
            words, pos = zip(*(self.vectorizer.encode(tokens) for tokens in token_lists))
            word_embs = torch.from_numpy(np.stack(words)).to(self.device)
        else:  # learned: rows of the trained table
            assert isinstance(self.vectorizer, LearnedWordVectors)
            ids, pos = zip(*(self.vectorizer.ids(tokens) for tokens in token_lists))
            word_embs = self.embedding(torch.from_numpy(np.stack(ids)).to(self.device))
        return word_embs, torch.from_numpy(np.stack(pos)).to(self.device)


def _embed(nets: dict[str, nn.Module], text_inputs: _TextInputs, batch: dict[str, Any],
           device: torch.device) -> tuple[Tensor, Tensor]:
    """Text and motion embeddings (B, E) of a collated evaluation batch, in batch order."""
    motion = batch["motion"].to(device)  # (B, 196, D), zero past each length
    with torch.no_grad():  # the movement encoder is frozen
        movements = nets["movement_encoder"](motion[..., :-FOOT_CONTACT_DIMS])  # (B, 49, latent)
    motion_emb = nets["motion_encoder"](movements, batch["length"] // UNIT_LENGTH)
    word_embs, pos = text_inputs(batch["tokens"])
    return nets["text_encoder"](word_embs, pos, batch["sent_len"]), motion_emb


def _train_decomp(nets: dict[str, nn.Module], decoder: MovementConvDecoder, windows: _Windows,
                  steps: int, config: EvaluatorTrainConfig, generator: torch.Generator,
                  device: torch.device, progress: bool) -> list[float]:
    """Stage A (DecompTrainerV3): the movement autoencoder; returns the loss of each step."""
    from tqdm.auto import tqdm

    encoder = nets["movement_encoder"]
    encoder.train()
    decoder.train()
    optimizer = torch.optim.Adam([*encoder.parameters(), *decoder.parameters()],
                                 lr=config.decomp_lr)
    losses = []
    for _ in tqdm(range(steps), desc="evaluator A (movement AE)", disable=not progress,
                  dynamic_ncols=True):
        x = windows.batch(config.decomp_batch_size, generator).to(device)  # (B, W, D)
        latents = encoder(x[..., :-FOOT_CONTACT_DIMS])  # (B, W / 4, latent)
        loss = (F.l1_loss(decoder(latents), x) + config.lambda_sparsity * latents.abs().mean()
                + config.lambda_smooth * F.l1_loss(latents[:, 1:], latents[:, :-1]))
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        losses.append(loss.item())
    return losses


def _fixed_batches(dataset: Text2MotionEvalDataset, batch_size: int) -> list[dict[str, Any]]:
    """The validation set drawn once (captions, crops): losses comparable across checks."""
    samples = [dataset[i] for i in range(len(dataset))]
    chunks = [samples[i:i + batch_size] for i in range(0, len(samples), batch_size)]
    return [collate(chunk) for chunk in chunks if len(chunk) >= 2]


@torch.no_grad()
def _validation_loss(nets: dict[str, nn.Module], text_inputs: _TextInputs,
                     batches: list[dict[str, Any]], margin: float, device: torch.device) -> float:
    """Mean matching loss over fixed batches; shift 1, so the same negatives at every check."""
    losses = []
    for batch in batches:
        loss_pos, loss_neg = matching_loss(*_embed(nets, text_inputs, batch, device),
                                           batch["caption"], 1, margin)
        losses.append(float(loss_pos + loss_neg))
    return float(np.mean(losses))


def _train_match(nets: dict[str, nn.Module], text_inputs: _TextInputs,
                 dataset: Text2MotionEvalDataset, val_batches: list[dict[str, Any]],
                 steps: int, batch_size: int, config: EvaluatorTrainConfig, seed: int,
                 device: torch.device, progress: bool) -> dict[str, Any]:
    """Stage B (TextMotionMatchTrainer); leaves the kept (lowest validation loss) weights."""
    from tqdm.auto import tqdm

    nets["movement_encoder"].eval()
    nets["movement_encoder"].requires_grad_(False)
    text_side = list(nets["text_encoder"].parameters())
    if text_inputs.embedding is not None:
        text_side += list(text_inputs.embedding.parameters())
    motion_side = list(nets["motion_encoder"].parameters())
    optimizer = torch.optim.Adam([{"params": text_side}, {"params": motion_side}],
                                 lr=config.match_lr)  # Adam is per parameter: as two optimizers
    trained = [nets["text_encoder"], nets["motion_encoder"]]
    if text_inputs.embedding is not None:
        trained.append(text_inputs.embedding)
    order = _epochs(len(dataset), batch_size, _generator(seed, 3))
    shifts = _generator(seed, 4)
    losses: list[float] = []
    val_losses: dict[int, float] = {}
    best: tuple[float, int, list[dict[str, Tensor]]] | None = None
    bar = tqdm(range(1, steps + 1), desc="evaluator B (text-motion)", disable=not progress,
               dynamic_ncols=True)
    for step in bar:
        for module in trained:
            module.train()
        batch = collate([dataset[i] for i in next(order)])
        text_emb, motion_emb = _embed(nets, text_inputs, batch, device)
        shift = int(torch.randint(1, batch_size, (1,), generator=shifts))
        loss_pos, loss_neg = matching_loss(text_emb, motion_emb, batch["caption"], shift,
                                           config.margin)
        loss = loss_pos + loss_neg
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        nn.utils.clip_grad_norm_(text_side, config.clip_norm)
        nn.utils.clip_grad_norm_(motion_side, config.clip_norm)
        optimizer.step()
        losses.append(loss.item())
        if step % 10 == 0 or step == steps:
            bar.set_postfix(loss=f"{np.mean(losses[-10:]):.3f}")
        if val_batches and (step % config.val_every == 0 or step == steps):
            for module in trained:
                module.eval()
            val = _validation_loss(nets, text_inputs, val_batches, config.margin, device)
            val_losses[step] = val
            if best is None or val < best[0]:
                best = (val, step, [{k: v.detach().clone() for k, v in m.state_dict().items()}
                                    for m in trained])
    best_step = steps
    if best is not None:
        _, best_step, states = best
        for module, state in zip(trained, states):
            module.load_state_dict(state)
    for module in trained:
        module.eval()
    return {"losses": losses, "val_losses": val_losses, "best_step": best_step}


def _train_motions(layout: DatasetLayout, skel: Skeleton, mean: np.ndarray,
                   std: np.ndarray) -> list[np.ndarray]:
    """Stage A's data: the train split's whole motions, normalized (bad files: as the dataset)."""
    motions = []
    for name in layout.read_split("train"):
        try:
            motions.append((layout.load_features(name, skel) - mean) / std)
        except BadFileError:
            pass  # the strict dataset has already raised; with on_bad_file="skip" it warned
    return motions


def train_evaluator(data_dir: str | os.PathLike, out_dir: str | os.PathLike, *,
                    glove_dir: str | os.PathLike | None = None, steps_decomp: int = 5000,
                    steps_match: int = 15000, batch_size: int = 32, seed: int = 0,
                    device: str | torch.device | None = "cpu", progress: bool = True,
                    config: EvaluatorTrainConfig | None = None, skeleton: str | None = None,
                    on_bad_file: Literal["strict", "skip"] = "strict",
                    overwrite: bool = False) -> dict[str, Any]:
    """Train the evaluator on the train split of `data_dir`; write a self-contained `out_dir`.

    Stage A: movement autoencoder, `steps_decomp` steps; stage B: text-motion co-embedding,
    `steps_match` steps of `batch_size` pairs. Word vectors: GloVe from `glove_dir` (fixed, as
    the reference), else learned from the training captions. Returns a summary: JSON-friendly
    entries (losses per step, validation losses, seconds) and 'evaluator', the trained Evaluator
    as `load_evaluator_dir(out_dir)` rebuilds it.
    """
    config = EvaluatorTrainConfig() if config is None else config
    if steps_decomp < 0 or steps_match < 0:
        raise MlctError(f"step counts must be >= 0, got {steps_decomp} and {steps_match}")
    if batch_size < 2:
        raise MlctError(f"batch_size must be at least 2 (negatives pair within a batch), "
                        f"got {batch_size}")
    if config.val_every < 1 or config.window_size < UNIT_LENGTH or config.feat_bias <= 0:
        raise MlctError("config: val_every >= 1, window_size >= 4 and feat_bias > 0 needed")
    if glove_dir is not None and config.sizes.word != WORD_DIM:
        raise MlctError(f"GloVe vectors are {WORD_DIM}-d; sizes.word is {config.sizes.word}")
    dev = resolve_device(device)
    out = Path(out_dir)
    prepare_target(out, overwrite)

    layout = DatasetLayout.existing(data_dir)
    skel = layout.skeleton(skeleton)
    mean, std = evaluator_mean_std(*layout.load_mean_std(skel), skel, config.feat_bias)
    dataset = Text2MotionEvalDataset(layout.root, "train", skeleton=skel, mean=mean, std=std,
                                     on_bad_file=on_bad_file, generator=_generator(seed, 2))
    if len(dataset) < batch_size:
        raise MlctError(f"{layout.split_path('train')}: {len(dataset)} caption-motion items, "
                        f"fewer than batch_size {batch_size}")
    val_batches: list[dict[str, Any]] = []
    if layout.split_path("val").is_file():
        val = Text2MotionEvalDataset(layout.root, "val", skeleton=skel, mean=mean, std=std,
                                     on_bad_file=on_bad_file, generator=_generator(seed, 5))
        val_batches = _fixed_batches(val, batch_size)
    windows = _Windows(_train_motions(layout, skel, mean, std), config.window_size)
    if glove_dir is not None:
        vectorizer: WordVectorizer = WordVectorizer(glove_dir, GLOVE_PREFIX)
    else:
        words = build_vocabulary(r.tokens for item in dataset.items for r in item.captions)
        vectorizer = LearnedWordVectors.initial(words, config.sizes.word,
                                                np.random.default_rng([seed, 6]))

    devices = [] if dev.type != "cuda" else [
        dev.index if dev.index is not None else torch.cuda.current_device()]
    with torch.random.fork_rng(devices=devices):  # init and dropout; the caller's RNG is kept
        torch.manual_seed(seed)
        nets = {k: m.to(dev) for k, m in build_networks(skel.feature_dim,
                                                                  config.sizes).items()}
        decoder = MovementConvDecoder(config.sizes.movement_latent, config.sizes.movement_hidden,
                                      skel.feature_dim).to(dev)
        embedding = None
        if isinstance(vectorizer, LearnedWordVectors):
            embedding = nn.Embedding.from_pretrained(torch.from_numpy(vectorizer.vectors).clone(),
                                                     freeze=False).to(dev)
        text_inputs = _TextInputs(vectorizer, embedding, dev)
        started = time.perf_counter()
        decomp_losses = _train_decomp(nets, decoder, windows, steps_decomp, config,
                                      _generator(seed, 1), dev, progress)
        middle = time.perf_counter()
        match = _train_match(nets, text_inputs, dataset, val_batches, steps_match, batch_size,
                             config, seed, dev, progress)
        ended = time.perf_counter()

    if embedding is not None:  # the trained table replaces the initial one
        assert isinstance(vectorizer, LearnedWordVectors)
        vectorizer = LearnedWordVectors(vectorizer.words, embedding.weight.detach().cpu().numpy())
    steps_per_epoch = len(dataset) // batch_size
    evaluator = Evaluator({k: m.cpu() for k, m in nets.items()}, mean, std, vectorizer,
                          epoch=match["best_step"] // steps_per_epoch)
    summary = {
        "path": str(out), "feature_dim": skel.feature_dim, "skeleton": skel.name,
        "vocabulary": "glove" if embedding is None else "learned",
        "vocabulary_size": len(vectorizer), "train_items": len(dataset),
        "val_items": sum(len(b["caption"]) for b in val_batches), "seed": seed,
        "batch_size": batch_size, "steps_decomp": steps_decomp, "steps_match": steps_match,
        "best_step": match["best_step"], "val_losses": match["val_losses"],
        "decomp_losses": decomp_losses, "match_losses": match["losses"],
        "seconds_decomp": middle - started, "seconds_match": ended - middle,
    }
    skip = ("path", "decomp_losses", "match_losses")
    meta = {
        "skeleton": skel.name,
        "normalization": {
            "dataset": str(layout.root.resolve()), "feat_bias": config.feat_bias,
            "rule": "the dataset's Mean/Std, the std of these groups divided by feat_bias",
            "groups": list(FEAT_BIAS_GROUPS)},
        "config": asdict(config),
        "training": {k: v for k, v in summary.items() if k not in skip}
        | {"final_decomp_loss": decomp_losses[-1] if decomp_losses else None,
           "final_match_loss": match["losses"][-1] if match["losses"] else None},
    }
    decomp = {"movement_enc": evaluator.movement_encoder.state_dict(),
              "movement_dec": decoder.cpu().state_dict()}
    write_evaluator_dir(out, evaluator, config.sizes, glove_dir=glove_dir, meta=meta,
                        states={DECOMP_FILE: decomp})
    return summary | {"evaluator": evaluator}
