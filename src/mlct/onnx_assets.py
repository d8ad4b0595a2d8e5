"""The bundled model's ONNX graphs, shipped inside the package, and the MiniLM they read.

`pip install mlct` runs the bundled model with ONNX Runtime and no torch, so its graphs cannot
be converted on first use (that traces the torch networks): they are made once, here, and
committed beside the weights they come from:

    assets/model/onnx/            denoiser.onnx, decoder.onnx, text_encoder.onnx, onnx.json
                                  (backends/onnx/bundle.py's format: the manifest records the
                                  sha256 of the model.safetensors they were made from, and the
                                  loader refuses graphs of other weights), and critic.onnx, the
                                  critic's score (z (B, n, d), frames (B,), text (B, c)) -> (B,),
                                  with the sha256 of the critic.safetensors it came from
    assets/model/onnx/text_encoder.weights.json
                                  the text encoder graph holds no weights: they are read from
                                  assets/minilm/model.safetensors at load, the one copy the
                                  torch encoder reads too (by ONNX Runtime at the tensors'
                                  offsets, the attentions' joined q, k, v by this recipe:
                                  onnx_io.externalize_weights)
    assets/minilm/                sentence-transformers/all-MiniLM-L6-v2 (Apache-2.0): config,
                                  tokenizer, weights, as the Hugging Face repository has them

    python -m mlct.onnx_assets    write them again (after the bundled model changes; needs the
                                  train extra: torch traces the networks)

tests/test_onnx_assets.py checks that the shipped graphs match the bundled weights (the recorded
digests, and the same motions for the same seed on the onnx and torch backends).
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from mlct.shipped import (ASSETS, CRITIC, CRITIC_WEIGHTS, MINILM_DIR, MINILM_WEIGHTS,
                          MODEL_DIR, SHIPPED_DIR, TEXT_ENCODER_WEIGHTS, file_digest)

# all-MiniLM-L6-v2's files that the encoders read (the tokenizer, BERT's sizes, the
# sentence-transformers pipeline, the weights) and its model card (the license, where from)
MINILM_FILES = ("config.json", "config_sentence_transformers.json", "modules.json",
                "sentence_bert_config.json", "special_tokens_map.json", "tokenizer.json",
                "tokenizer_config.json", "vocab.txt", "1_Pooling/config.json", "README.md",
                MINILM_WEIGHTS)
CRITIC_IO = (("z", "frames", "text"), ("score",))


def copy_minilm(source: Path, into: Path = MINILM_DIR) -> Path:
    """Copy all-MiniLM-L6-v2's files from a sentence-transformers directory into `into`."""
    for name in MINILM_FILES:
        (into / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source / name, into / name)
    return into


def write_shipped_graphs(model_dir: Path = MODEL_DIR, into: Path = SHIPPED_DIR,
                         minilm: Path = MINILM_DIR) -> Path:
    """Write the float32 graphs of the model in model_dir into `into` (replaced whole), the text
    encoder's weights left in minilm/model.safetensors; returns `into`."""
    from mlct.generate.backends.onnx.bundle import MANIFEST, TEXT_ENCODER
    from mlct.generate.backends.onnx.convert import write_onnx_graphs
    from mlct.io import atomic_dir
    from mlct.onnx_io import externalize_weights

    weights = minilm / MINILM_WEIGHTS
    with atomic_dir(into) as work:
        write_onnx_graphs(model_dir, work)
        relative = Path("..", *[".."] * (len(into.relative_to(ASSETS).parts) - 1),
                        minilm.relative_to(ASSETS), MINILM_WEIGHTS)
        externalize_weights(work / TEXT_ENCODER, weights, relative.as_posix())
        manifest = json.loads((work / MANIFEST).read_text(encoding="utf-8"))
        manifest[TEXT_ENCODER_WEIGHTS] = file_digest(weights)
        if write_critic_graph(model_dir, work / CRITIC):
            manifest["graphs"]["critic"] = CRITIC
            manifest[CRITIC_WEIGHTS] = file_digest(model_dir / "critic.safetensors")
        (work / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8")
    return into


def write_critic_graph(model_dir: Path, path: Path) -> bool:
    """Write the critic's score of the model in model_dir as an ONNX graph at path, checked
    against the torch network; False (nothing written) when the model has no critic."""
    import torch

    from mlct.config import config_from_dict
    from mlct.generate.bundle import read_config
    from mlct.generate.compose.critic import read_critic
    from mlct.onnx_io import export_graph, session

    meta = read_config(model_dir)
    ae = config_from_dict(meta["config"], "model config").ae
    critic = read_critic(model_dir, meta["text_encoder"], int(meta["text_dim"]),
                         ae.n_tokens * ae.latent_dim)
    if critic is None:
        return False
    net, info = critic.network, critic.info
    probe = torch.Generator().manual_seed(0)

    class Score(torch.nn.Module):
        def forward(self, z, frames, text):  # noqa: D102 - (B, n, d), (B,), (B, c) -> (B,)
            return net.score(z, frames, text)

    z = torch.randn(3, ae.n_tokens, ae.latent_dim, generator=probe)
    frames = torch.tensor([40.0, 100.0, 196.0])
    text = torch.randn(3, info["text_dim"], generator=probe)
    batch = {0: "batch"}
    export_graph(Score(), (z, frames, text), path, *CRITIC_IO,
                 {name: batch for name in (*CRITIC_IO[0], *CRITIC_IO[1])})
    (got,) = session(path, threads=1).run(None, {"z": z.numpy(), "frames": frames.numpy(),
                                                 "text": text.numpy()})
    with torch.no_grad():
        gap = float(abs(got - Score()(z, frames, text).numpy()).max())
    if not gap <= 1e-5:
        raise ValueError(f"{path.name}: the critic's graph differs from its network by {gap:.3g}")
    return True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mlct.onnx_assets", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--minilm-from", type=Path, default=None,
                        help="copy all-MiniLM-L6-v2 from this sentence-transformers directory "
                             "into assets/minilm first")
    args = parser.parse_args(argv)
    if args.minilm_from is not None:
        copy_minilm(args.minilm_from)
    into = write_shipped_graphs()
    for path in sorted(into.iterdir()):
        print(f"{path}  {path.stat().st_size / 1e6:.2f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
