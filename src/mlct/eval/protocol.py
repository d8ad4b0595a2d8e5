"""The standard text-to-motion evaluation protocol (Guo et al. 2022, as MLD and MLCT run it).

Facts from EricGuo5513/text-to-motion (final_evaluations.py, motion_loaders/, utils/metrics.py)
and ChenFengYe/motion-latent-diffusion (mld/models/modeltype/mld.py t2m_eval, metrics/tm2t.py,
metrics/mm.py), read, not copied:
- the test items come from the evaluation dataset: a random caption of the motion, the motion
  cropped to a multiple of 4 frames (one unit shorter a third of the time), batches of 32,
  shuffled, the last incomplete batch dropped;
- every generated motion takes its item's caption and ground-truth (cropped) length; generated
  and real features are normalized by the evaluator's own Mean/Std (MLD's renorm4t2m);
- per replication: R-precision top-1/2/3 in groups of 32 and MM-Dist against the items' text
  embeddings, FID against the real motions' embeddings, Diversity over 300 pairs, MultiModality
  over 100 texts x 30 generations (10 pairs each);
- 20 replications, reported as mean +- 1.96 std / sqrt(20).

Choices where the references leave room (also written into each report):
- The real side is drawn once (one seeded caption and crop per item, with `seed`) and embedded
  once; every replication and every configuration of a run reuses these features. A replication
  reshuffles which items form the groups of 32 and which are dropped. (The reference redraws the
  captions and crops in every replication.)
- The generated and the Real rows use the same text embeddings (as MLD), and FID's real
  statistics are the real embeddings of the replication's kept items: Real's FID is 0 up to
  rounding.
- Replication r draws everything from seed + r: the shuffle, the diversity pairs, the
  MultiModality texts and pairs, and the sampling noise (batch b samples with a seed derived
  from (seed + r, b)). Real and generated rows, and all configurations, share these draws.
- Diversity takes 300 pairs, or kept - 1 where a replication keeps 300 items or fewer (the
  procedural benchmark's 300-motion test split keeps 288); MultiModality takes 100 texts, or
  every item of a smaller split. Explicit values are checked instead.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np
import torch

from mlct.data.dataset import MAX_MOTION_LENGTH, Text2MotionEvalDataset
from mlct.data.layout import DatasetLayout
from mlct.errors import MlctError
from mlct.eval.judge.action_classifier import (ActionClassifier, action_records,
                                               action_targets, load_action_classifier,
                                               semantic_accuracy)
from mlct.eval.aits import time_inference
from mlct.eval.judge.evaluator import Evaluator
from mlct.eval.judge.evaluator_dir import load_evaluator_dir, read_evaluator_meta
from mlct.eval.metrics import (
    DIVERSITY_TIMES,
    MULTIMODALITY_TIMES,
    R_PRECISION_GROUP,
    confidence_interval,
    diversity,
    fid,
    matching_score,
    multimodality,
    r_precision_batched,
)
from mlct.motion.skeleton import Skeleton
from mlct.generate.compose.generator import MotionGenerator

REPLICATIONS = 20
MM_TEXTS = 100  # mm_num_samples
MM_GENERATIONS = 30  # mm_num_repeats
METRICS = ("r_precision_top1", "r_precision_top2", "r_precision_top3", "fid", "mm_dist",
           "diversity", "multimodality", "semantic_exact", "semantic_recall")
NOISE_STREAM, MM_STREAM = 0, 1  # seed streams of the generations of a replication

Log = Callable[[str], None]


@dataclass(frozen=True)
class ProtocolConfig:
    """The protocol's numbers; the defaults are the paper's. Tests shrink them."""

    reps: int = REPLICATIONS
    seed: int = 0  # replication r uses seed + r; the real side's captions and crops use seed
    batch_size: int = R_PRECISION_GROUP  # R-precision group, generation batch, drop_last unit
    diversity_times: int | None = None  # None: 300, or kept - 1 on a small split
    mm: bool = False  # MultiModality (costs mm_texts x mm_generations generations a replication)
    mm_texts: int | None = None  # None: 100, or every item of a smaller split
    mm_generations: int = MM_GENERATIONS
    mm_times: int = MULTIMODALITY_TIMES
    aits_runs: int = 10  # timed runs at batch 1 (0: no timing)
    aits_warmup: int = 3
    aits_frames: int = MAX_MOTION_LENGTH  # 196 frames; less when the model makes fewer


@dataclass(frozen=True)
class RealFeatures:
    """The test items as drawn once (caption, cropped length) and their evaluator embeddings."""

    names: list[str]
    captions: list[str]
    lengths: np.ndarray  # (N,) frames
    text: np.ndarray  # (N, E) text embeddings of the captions
    motion: np.ndarray  # (N, E) embeddings of the real motions
    features: list[np.ndarray] | None = None  # (T_i, D) real units; kept for a SemanticJudge


@dataclass(frozen=True)
class SemanticJudge:
    """Semantic accuracy (beyond the paper): the benchmark's action classifier, and the classes
    each test item's prompt asks for (labels.jsonl), by dataset index."""

    classifier: ActionClassifier
    targets: list[set[str]]

    def score(self, features: Sequence[np.ndarray], idx: np.ndarray
              ) -> tuple[dict[str, float], dict[str, float]]:
        """(exact-set accuracy and mean recall, per-class recall) of motions for items idx."""
        result = semantic_accuracy(self.classifier, features, [self.targets[i] for i in idx])
        return ({"semantic_exact": result["exact_set_accuracy"],
                 "semantic_recall": result["mean_recall"]}, result["recall"])


@dataclass
class RowResult:
    """One row of the results table: a configuration (or Real) over all replications."""

    method: str
    kind: str  # "real", "consistency" (MLCT) or "ddim" (diffusion baseline)
    model: str | None = None
    nfe: int | None = None  # sampling steps: denoiser evaluations (consistency: nfe; DDIM: steps)
    network_passes: int | None = None  # DDIM with CFG runs the denoiser on cond and uncond
    guidance: float | None = None  # consistency: the w trained in; DDIM: the CFG scale
    metrics: dict[str, dict[str, Any]] = field(default_factory=dict)  # mean, ci, values
    timing: dict[str, Any] | None = None
    seconds: float = 0.0
    semantic_recall: dict[str, float] | None = None  # per class, mean over replications

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def mean_recall_per_class(replications: Sequence[dict[str, float]]) -> dict[str, float] | None:
    """Per-class recalls of several replications -> their mean per class (None: none given)."""
    if not replications:
        return None
    classes = sorted({k for rep in replications for k in rep})
    return {k: float(np.mean([rep[k] for rep in replications if k in rep])) for k in classes}


def summarize(replications: Sequence[dict[str, float]]) -> dict[str, dict[str, Any]]:
    """Per-replication metric dicts -> {name: {mean, ci, values}}, ci = 1.96 std / sqrt(n)."""
    out = {}
    for name in METRICS:
        values = [rep[name] for rep in replications if name in rep]
        if values:
            mean, ci = confidence_interval(values)
            out[name] = {"mean": mean, "ci": ci, "values": values}
    return out


def _seed(*words: int) -> int:
    """A 63-bit torch seed derived from integers (the replication, a stream, a batch index)."""
    return int(np.random.SeedSequence(list(words)).generate_state(1, np.uint64)[0] >> np.uint64(1))


def embed_features(evaluator: Evaluator, features: Sequence[np.ndarray]) -> np.ndarray:
    """Motions in real units, (T_i, D) each -> (B, E) evaluator embeddings (its Mean/Std)."""
    lengths = [len(f) for f in features]
    batch = torch.zeros(len(features), max(lengths), evaluator.feature_dim)
    for i, motion in enumerate(features):
        batch[i, :len(motion)] = torch.as_tensor(motion, dtype=torch.float32)
    return evaluator.embed_motion(evaluator.normalize(batch), lengths).cpu().numpy()


def embed_real(dataset: Text2MotionEvalDataset, evaluator: Evaluator,
               batch_size: int = 128, keep_features: bool = False) -> RealFeatures:
    """Draw every item once (its dataset's seeded caption and crop) and embed text and motion."""
    samples = [dataset[i] for i in range(len(dataset))]
    texts, motions, kept = [], [], []
    for start in range(0, len(samples), batch_size):
        chunk = samples[start:start + batch_size]
        words, pos = evaluator.tokens_to_tensors([s.tokens for s in chunk])
        texts.append(evaluator.embed_text(words, pos, [s.sent_len for s in chunk]).cpu().numpy())
        raw = dataset.denormalize(torch.stack([s.motion for s in chunk]))  # real units
        motions.append(evaluator.embed_motion(evaluator.normalize(raw),
                                              [s.length for s in chunk]).cpu().numpy())
        if keep_features:
            kept += [raw[i, :s.length].numpy() for i, s in enumerate(chunk)]
    return RealFeatures([dataset.name(i) for i in range(len(samples))],
                        [s.caption for s in samples], np.array([s.length for s in samples]),
                        np.concatenate(texts), np.concatenate(motions),
                        kept if keep_features else None)


def generated_embeddings(gen: MotionGenerator, evaluator: Evaluator, captions: Sequence[str],
                         lengths: Sequence[int], *, nfe: int | None, guidance: float | None,
                         seeds: Sequence[int], batch_size: int,
                         keep: list[np.ndarray] | None = None) -> np.ndarray:
    """Generate for (caption, length) pairs in batches (batch b seeded by seeds[b]); embed.
    The generated features (real units) are appended to `keep` when one is given."""
    out = []
    for b, start in enumerate(range(0, len(captions), batch_size)):
        texts = list(captions[start:start + batch_size])
        frames = [int(n) for n in lengths[start:start + batch_size]]
        # generate() without the joints: the text -> latent -> features path it runs
        z = gen.sample_latents(gen.encode_text(texts), nfe, seeds[b], guidance)
        features = gen.decode(z, frames)
        out.append(embed_features(evaluator, features))
        if keep is not None:
            keep.extend(features)
    return np.concatenate(out)


class Protocol:
    """One test split measured by one evaluator; the real side is embedded once and cached."""

    def __init__(self, evaluator: Evaluator, dataset: Text2MotionEvalDataset,
                 config: ProtocolConfig = ProtocolConfig(), log: Log | None = None,
                 judge: SemanticJudge | None = None) -> None:
        self.evaluator = evaluator
        self.dataset = dataset
        self.judge = judge
        self.log = log or (lambda message: None)
        self.config = resolve_config(config, len(dataset))
        self._real: RealFeatures | None = None

    @property
    def kept(self) -> int:
        """Items a replication keeps: whole batches only (drop_last)."""
        return len(self.dataset) // self.config.batch_size * self.config.batch_size

    @property
    def real(self) -> RealFeatures:
        if self._real is None:
            started = time.perf_counter()
            self._real = embed_real(self.dataset, self.evaluator,
                                    keep_features=self.judge is not None)
            self.log(f"embedded {len(self._real.names)} real items "
                     f"({time.perf_counter() - started:.1f} s)")
        return self._real

    def order(self, rep: int) -> tuple[np.ndarray, np.random.Generator]:
        """Replication rep's kept items (shuffled, drop_last) and its generator (seed + rep)."""
        rng = np.random.default_rng(self.config.seed + rep)
        return rng.permutation(len(self.dataset))[:self.kept], rng

    def _metrics(self, idx: np.ndarray, motion: np.ndarray,
                 rng: np.random.Generator) -> dict[str, float]:
        text, real = self.real.text[idx], self.real.motion[idx]
        top = r_precision_batched(text, motion, self.config.batch_size)  # groups in order
        times = self.config.diversity_times
        assert times is not None
        return {"r_precision_top1": float(top[0]), "r_precision_top2": float(top[1]),
                "r_precision_top3": float(top[2]), "fid": fid(real, motion),
                "mm_dist": matching_score(text, motion),
                "diversity": diversity(motion, times, rng=rng)}

    def real_replication(self, rep: int) -> dict[str, Any]:
        """The Real row's metrics in replication rep (the real motions as the 'generations')."""
        idx, rng = self.order(rep)
        out: dict[str, Any] = self._metrics(idx, self.real.motion[idx], rng)
        if self.judge is not None:
            assert self.real.features is not None
            scores, out["per_class"] = self.judge.score([self.real.features[i] for i in idx], idx)
            out.update(scores)
        return out

    def replication(self, gen: MotionGenerator, rep: int, nfe: int | None = None,
                    guidance: float | None = None) -> dict[str, Any]:
        """One replication of a model configuration: generate for the kept items, measure."""
        cfg = self.config
        idx, rng = self.order(rep)
        seed = cfg.seed + rep
        # Every caption of the split is encoded in one call before any is used: an encoder's
        # output depends slightly on its batch (padding), so this keeps the numbers independent
        # of which configurations ran before on this generator (its memo is then full).
        gen.encode_text(sorted(set(self.real.captions)))
        batches = range(-(-len(idx) // cfg.batch_size))
        features: list[np.ndarray] | None = [] if self.judge is not None else None
        motion = generated_embeddings(
            gen, self.evaluator, [self.real.captions[i] for i in idx], self.real.lengths[idx],
            nfe=nfe, guidance=guidance, seeds=[_seed(seed, NOISE_STREAM, b) for b in batches],
            batch_size=cfg.batch_size, keep=features)
        out: dict[str, Any] = self._metrics(idx, motion, rng)
        if self.judge is not None:
            assert features is not None
            scores, out["per_class"] = self.judge.score(features, idx)
            out.update(scores)
        if cfg.mm:
            assert cfg.mm_texts is not None
            chosen = rng.choice(len(self.dataset), cfg.mm_texts, replace=False)
            repeated = np.repeat(chosen, cfg.mm_generations)  # each text mm_generations times
            batches = range(-(-len(repeated) // cfg.batch_size))
            mm = generated_embeddings(
                gen, self.evaluator, [self.real.captions[i] for i in repeated],
                self.real.lengths[repeated], nfe=nfe, guidance=guidance,
                seeds=[_seed(seed, MM_STREAM, b) for b in batches], batch_size=cfg.batch_size)
            out["multimodality"] = multimodality(
                mm.reshape(cfg.mm_texts, cfg.mm_generations, -1), cfg.mm_times, rng=rng)
        return out

    def evaluate_real(self) -> RowResult:
        """The Real row: the real motions measured like generations, every replication."""
        started = time.perf_counter()
        reps = [self.real_replication(r) for r in range(self.config.reps)]
        return RowResult("Real", "real", metrics=summarize(reps),
                         seconds=time.perf_counter() - started,
                         semantic_recall=mean_recall_per_class(
                             [r["per_class"] for r in reps if "per_class" in r]))

    def evaluate(self, gen: MotionGenerator, nfe: int | None = None,
                 guidance: float | None = None, method: str = "model",
                 model: str | None = None) -> RowResult:
        """A configuration (model, nfe, guidance) over all replications, then its AITS."""
        steps = gen.check_nfe(nfe)
        sampler = gen.sampler
        scale = sampler.guidance(guidance)  # consistency: the w trained in; DDIM: the CFG scale
        cfg = self.config
        started = time.perf_counter()
        reps = []
        for r in range(cfg.reps):
            reps.append(self.replication(gen, r, steps, scale))
            self.log(f"{method}: replication {r + 1}/{cfg.reps} "
                     f"({time.perf_counter() - started:.1f} s)")
        seconds = time.perf_counter() - started
        timing = None
        if cfg.aits_runs > 0:
            timing = time_inference(gen, self.real.captions, nfe=steps,
                                    guidance=scale,
                                    frames=min(cfg.aits_frames, gen.max_frames),
                                    runs=cfg.aits_runs, warmup=cfg.aits_warmup)
        return RowResult(method, sampler.name, model, steps, sampler.passes_per_step * steps,
                         scale, summarize(reps), timing, seconds,
                         mean_recall_per_class([r["per_class"] for r in reps
                                                if "per_class" in r]))


def resolve_config(config: ProtocolConfig, items: int) -> ProtocolConfig:
    """Fill the size-dependent defaults for a split of `items` items and check what was given."""
    if config.reps < 1:
        raise MlctError(f"reps must be at least 1, got {config.reps}")
    if config.batch_size < 3:
        raise MlctError(f"batch size must be at least 3 (R-precision top-3), "
                        f"got {config.batch_size}")
    kept = items // config.batch_size * config.batch_size
    if kept == 0:
        raise MlctError(f"the split has {items} items, fewer than one R-precision group of "
                        f"{config.batch_size}")
    times = config.diversity_times
    if times is None:
        times = min(DIVERSITY_TIMES, kept - 1)
    elif not 1 <= times < kept:
        raise MlctError(f"diversity over {times} pairs needs more than {times} items; a "
                        f"replication keeps {kept} (whole batches of {config.batch_size})")
    mm_texts = config.mm_texts
    if config.mm:
        mm_texts = min(MM_TEXTS, items) if mm_texts is None else mm_texts
        if not 1 <= mm_texts <= items:
            raise MlctError(f"MultiModality over {mm_texts} texts needs as many items; the "
                            f"split has {items}")
        if config.mm_generations <= config.mm_times or config.mm_times < 1:
            raise MlctError(f"MultiModality needs more generations per text "
                            f"({config.mm_generations}) than pairs ({config.mm_times}) >= 1")
    if config.aits_runs < 0 or config.aits_warmup < 0 or config.aits_frames < 1:
        raise MlctError("AITS runs and warm-up must be >= 0 and its frames >= 1")
    return replace(config, diversity_times=times, mm_texts=mm_texts)


# ------------------------------------------------------------------------- inputs, checked


def _missing_stats(root: Path, what: str, how: str) -> None:
    for name in ("Mean.npy", "Std.npy"):
        if not (root / name).is_file():
            raise MlctError(f"{root / name}: missing ({what}; {how})")


def check_inputs(data_dir: str | Path, evaluator_dir: str | Path,
                 models: Sequence[tuple[str | Path, dict[str, Any]]] = (),
                 split: str = "test") -> Skeleton:
    """Check data, evaluator and model metadata against each other before any work starts.

    `models` pairs a model directory with its bundle's config.json. Returns the skeleton.
    """
    layout = DatasetLayout.existing(data_dir)
    root = layout.root
    skel = layout.skeleton()
    _missing_stats(root, "the dataset's normalization statistics",
                   f"write them with `mlct data stats {root}`")
    if not layout.split_path(split).is_file():
        raise MlctError(f"{layout.split_path(split)}: missing (no split {split!r})")
    eval_root = Path(evaluator_dir)
    if not eval_root.is_dir():
        raise MlctError(f"{eval_root}: no such evaluator directory")
    meta = read_evaluator_meta(eval_root)
    _missing_stats(eval_root, "the evaluator's own normalization statistics",
                   "the evaluator directory is incomplete")
    width = meta.get("feature_dim")
    if width != skel.feature_dim:
        raise MlctError(f"evaluator {eval_root} reads {width}-d motion features, the dataset "
                        f"{root} has {skel.feature_dim}-d ({skel.name}) features")
    if meta.get("skeleton", skel.name) != skel.name:
        raise MlctError(f"evaluator {eval_root} was trained on the {meta['skeleton']} skeleton, "
                        f"the dataset {root} is {skel.name}")
    for path, model in models:
        if model.get("skeleton") != skel.name or model.get("feature_dim") != skel.feature_dim:
            raise MlctError(f"model {path} was trained on {model.get('skeleton')} "
                            f"({model.get('feature_dim')}-d features), the dataset {root} is "
                            f"{skel.name} ({skel.feature_dim}-d)")
    return skel


def open_protocol(data_dir: str | Path, evaluator_dir: str | Path, split: str = "test",
                  config: ProtocolConfig = ProtocolConfig(), device: str | torch.device = "cpu",
                  log: Log | None = None,
                  models: Sequence[tuple[str | Path, dict[str, Any]]] = (),
                  classifier_dir: str | Path | None = None) -> Protocol:
    """Check the inputs (and the models' metadata), load the evaluator and the split's items,
    and the action classifier with every item's labels when classifier_dir is given.

    Nothing is embedded yet: the real side is embedded on first use.
    """
    skel = check_inputs(data_dir, evaluator_dir, models, split)
    judge = None
    if classifier_dir is not None:
        classifier = load_action_classifier(classifier_dir)
        classifier.check(skel.feature_dim, skel.name)
        labels = action_records(data_dir)
    evaluator = load_evaluator_dir(evaluator_dir).to(device)
    dataset = Text2MotionEvalDataset(data_dir, split, skeleton=skel, seed=config.seed)
    if classifier_dir is not None:
        names = [dataset.name(i) for i in range(len(dataset))]
        unlabeled = [n for n in names if n not in labels]
        if unlabeled:
            raise MlctError(f"{len(unlabeled)} items of split {split!r} have no action labels "
                            f"in {Path(data_dir)} (labels.jsonl or provenance.jsonl; first: "
                            f"{unlabeled[0]})")
        judge = SemanticJudge(classifier.to(device),
                              [action_targets(labels[n]) for n in names])
    return Protocol(evaluator, dataset, config, log, judge)


def check_model(protocol: Protocol, gen: MotionGenerator, steps: Sequence[int | None],
                path: str | Path) -> None:
    """The model can make every item's length and sample with every step count asked for."""
    unit = protocol.dataset.unit_length  # the longest crop the dataset can draw
    longest = min(int(protocol.dataset.lengths.max()),
                  protocol.dataset.max_motion_length) // unit * unit
    if gen.max_frames < longest:
        raise MlctError(f"model {path} makes at most {gen.max_frames} frames, the split has "
                        f"items of up to {longest} (train with data.max_motion_length={longest} "
                        f"or more)")
    for nfe in steps:
        try:
            gen.check_nfe(nfe)
        except MlctError as error:
            raise MlctError(f"model {path} ({gen.sampler.name}): {error}") from None

