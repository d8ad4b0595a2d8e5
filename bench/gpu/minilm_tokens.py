"""The rows of the shipped MiniLM's token embeddings that datasets' captions use, for a GPU run's
carry (bench/gpu/carry.sh keeps only those rows; the far side checks its own captions against
the list it was sent).

    python bench/gpu/minilm_tokens.py check KEPT_IDS_FILE DATASET ...   # exit 1 if one is missing
"""

from __future__ import annotations

import sys
from pathlib import Path

from tokenizers import Tokenizer

from mlct.data.layout import read_texts
from mlct.shipped import MINILM_DIR
from mlct.text.sides import mirror_sides


def dataset_captions(datasets: list[str]) -> set[str]:
    """Every caption of the datasets' texts/, each also with its sides mirrored (minilm+sides
    encodes both), and the empty caption of unconditional training."""
    captions = {""}
    for dataset in datasets:
        for path in sorted((Path(dataset) / "texts").glob("*.txt")):
            for record in read_texts(path):
                captions.update((record.caption, mirror_sides(record.caption)))
    return captions


def caption_token_ids(datasets: list[str]) -> set[int]:
    """The token ids that the captions of the datasets tokenize into, the special tokens with them."""
    tokenizer = Tokenizer.from_file(str(MINILM_DIR / "tokenizer.json"))
    ids = {int(tokenizer.token_to_id(t)) for t in ("[CLS]", "[SEP]", "[PAD]", "[UNK]")}
    for encoding in tokenizer.encode_batch(sorted(dataset_captions(datasets))):
        ids.update(encoding.ids)
    return ids


def main(argv: list[str]) -> int:
    if len(argv) < 3 or argv[0] != "check":
        print(__doc__.strip().splitlines()[-1].strip(), file=sys.stderr)
        return 2
    kept = {int(line) for line in Path(argv[1]).read_text().split()}
    missing = caption_token_ids(argv[2:]) - kept
    print(f"captions' token rows: {len(kept)} kept, {len(missing)} missing")
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
