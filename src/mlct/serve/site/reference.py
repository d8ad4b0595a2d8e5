"""The static site's motion in Python: what the page (serve/site/static/model.js) computes for a
prompt, a length and a seed, step for step, with the same functions generate() uses.

The page draws its noise from generate/samplers/portable_noise.py, encodes each text in a run of its own
(page_text_vector), and makes a prompt as generate() makes it: an arm action during another
apart, a sequence one part each and chained, a gait kept going, the best of the critic's
candidates, the feet planted. With load_site_reference (the onnx backend on the site's own
graphs) this gives the page's joints, which tests/test_web_static_e2e.py compares with the
page's, and bench/web_readouts.py scores without a browser.

    generator = load_site_reference("site/")
    features, joints = generate_with_portable_noise(generator, "a person jumps", 60, 5, seed=7)
"""

from __future__ import annotations

import numpy as np
import torch

from mlct.generate.compose.actions import plain_subject
from mlct.generate.samplers.portable_noise import PortableNoise


def generate_with_portable_noise(generator, text: str, frames: int | None, nfe: int | None,
                                 seed: int, split_actions: bool = True,
                                 candidates: int | None = None
                                 ) -> tuple[np.ndarray | None, np.ndarray]:
    """One motion as the static site makes it: the generator's own text encoder, sampler and
    decoder (any backend), the noise from PortableNoise(seed), texts encoded one at a time
    (page_text_vector), each prompt the best of `candidates` by the critic (None: the model's
    default, as the page's; candidate k's noise from PortableNoise(seed + k * SEED_STRIDE mod
    2^63), as MotionGenerator.sample_best seeds it), the feet planted. Unless
    split_actions is False, a prompt is made as generate() makes it (compose/generator.py): an arm
    action done during another (compose.split_concurrent) alone, standing, its arms put on the
    body made from the rest (control_fit.reattach), both with the seed; a sequence
    (compose.split_actions) one part each, its share from the duration model
    (MotionGenerator.part_frames), part k with seed + k as generate_long seeds it, chained
    (long_motion.chain_segments); a gait asked for longer than it lasts kept going
    (_whole_as_the_page). A phrase that
    says how long ("for 8 seconds", compose.lengths.stated_lengths) is taken out of the text; frames
    None: its seconds, else the default length (MotionGenerator.default_seconds).
    Returns (features (T, D), or None for a motion joined from parts, joints (T, J, 3)),
    float32."""
    from mlct.generate.compose.prompts import clean_prompt

    from mlct.generate.compose.lengths import stated_lengths

    text = clean_prompt(text)
    (text,), (stated,) = stated_lengths([text], split_actions)  # "... for 8 seconds"
    if frames is None and stated is not None:
        frames = generator.frames_for(stated)
    if frames is None:  # the page's length when it is given none (static/model.js)
        frames = generator.frames_for(generator.default_seconds([text], split_actions)[0])
    (frames,) = generator._lengths(1, int(frames), None, generator.longest_gait())
    steps = generator.check_nfe(nfe)
    if candidates is None:
        candidates = generator.candidates
    features, joints = _made_as_the_page(generator, text, frames, steps, seed, split_actions,
                                         candidates)
    if generator.foot_lock is not None:  # planted feet, as the page's lockFeet (motion.js)
        from mlct.motion.foot_lock import lock_feet

        joints = lock_feet(joints, generator.skeleton, generator.foot_lock).astype(np.float32)
    return features, joints


def _made_as_the_page(generator, text: str, frames: int, steps: int, seed: int, split: bool,
                      candidates: int) -> tuple[np.ndarray | None, np.ndarray]:
    """generate_with_portable_noise's motion before its feet are planted (static/model.js: make)."""
    from mlct.generate.compose.actions import split_actions, split_concurrent
    from mlct.generate.compose.long_motion import blend_frames, chain_segments
    from mlct.generate.compose.lengths import MIN_PART_SECONDS

    if split and (pair := split_concurrent(text)) is not None:
        from mlct.generate.control.schema import part_joints
        from mlct.generate.control.fit import reattach

        _, body = _made_as_the_page(generator, pair[0], frames, steps, seed, split, candidates)
        _, arms = _whole_as_the_page(generator, pair[1], frames, steps, seed, candidates)
        joints = reattach(arms.astype(np.float64), body.astype(np.float64),
                          part_joints("arms", generator.skeleton), generator.skeleton)
        return None, joints.astype(np.float32)
    parts = split_actions(text) if split else [text]
    # generate()'s rule: a sequence is split when each part gets MIN_PART_SECONDS
    if len(parts) == 1 or frames // len(parts) < generator.frames_for(MIN_PART_SECONDS):
        return _whole_as_the_page(generator, text, frames, steps, seed, candidates)
    blend = blend_frames(generator.skeleton.fps)
    share = generator.part_frames(parts, frames)
    lengths = [n + blend for n in share[:-1]] + [share[-1]]  # each covers the next's blend
    made = [_whole_as_the_page(generator, part, n, steps, seed + k, candidates)[1]
            for k, (part, n) in enumerate(zip(parts, lengths))]
    return None, chain_segments(made, blend, generator.skeleton)[0].astype(np.float32)


def _whole_as_the_page(generator, text: str, frames: int, steps: int, seed: int,
                       candidates: int) -> tuple[np.ndarray | None, np.ndarray]:
    """One prompt given to the model whole, as generate() makes it (MotionGenerator._made_each's "whole"
    items and _keep_going): a one-action gait asked for clearly longer than its natural length
    that stopped early, or for longer than the window (made at the window's length first), is
    made again as takes of that length (take k with seed + k), chained into one continuing
    motion (generate/compose/keep_going.py); (None, joints) then. Past the window anything else is the
    window's error, as in generate()."""
    from mlct.generate.compose.actions import split_actions, split_concurrent
    from mlct.generate.compose.keep_going import continue_gait, names_an_end
    from mlct.generate.compose.long_motion import blend_frames
    from mlct.generate.seeds import MAX_SEED
    from mlct.generate.compose.lengths import MIN_PART_SECONDS, too_long

    window = generator.max_frames
    features, joints = _one_with_portable_noise(generator, text, min(frames, window), steps,
                                                seed, candidates)
    fps = generator.skeleton.fps
    single = len(split_actions(text)) == 1 and split_concurrent(text) is None
    kept = None
    if (generator.durations is not None and generator.keep_going and not names_an_end(text)
            and frames / fps >= MIN_PART_SECONDS and single):
        natural = generator.durations.clip_seconds(
            np.asarray(torch.as_tensor(generator.encode_text([text])).float()))
        kept = continue_gait(
            joints, frames, window, natural, blend_frames(fps),
            generator.skeleton,
            lambda count, take: [_one_with_portable_noise(
                generator, text, take, steps, (seed + k) % (MAX_SEED + 1), candidates)[1]
                for k in range(count)])
    if kept is not None:
        return None, kept.joints.astype(np.float32)
    if frames > window:  # past the window only a gait goes on, as in generate()
        raise too_long(generator, frames, text=text)
    return features, joints


def _one_with_portable_noise(generator, text: str, frames: int, steps: int, seed: int,
                             candidates: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(features, joints) of one prompt as the model draws it, feet as decoded; the best of
    `candidates` latents by the model's critic (one sample without a critic)."""
    from mlct.generate.seeds import MAX_SEED, SEED_STRIDE
    from mlct.motion.features import recover_from_ric

    seeds = [seed] if candidates <= 1 or generator.critic is None else [
        (seed + k * SEED_STRIDE) % (MAX_SEED + 1) for k in range(candidates)]
    with torch.inference_mode():
        cond = page_text_vector(generator, text).to(generator.device)
        latents = []
        for s in seeds:
            noise = PortableNoise(s)
            x = generator.sampler.noise((1, *generator.ae.latent_shape), noise)  # x_T (1, n, d)
            latents.append(generator.sampler.sample(generator.denoiser, x, cond, steps,
                                                    generator=noise))
        z = torch.cat(latents)
        if len(seeds) > 1:
            best = generator.critic.best(z.float().cpu() / generator.config.schedule.latent_scale,
                                         torch.tensor([frames]), cond.float().cpu(), len(seeds))
            z = z[int(best[0])][None]
        (features,) = generator.decode(z, [frames])
        joints = recover_from_ric(torch.from_numpy(features)).numpy()
    return features, joints


def page_text_vector(generator, text: str) -> torch.Tensor:
    """(1, c) the text's vector as the page computes it (static/model.js: encode): one network
    run for the text and, for a 'minilm+sides' model, another for its mirror, contrasted as
    text/sides.py does. Not encode_text's one batch of both: export-web's `--text-encoder int8`
    quantizes a batch's activations together, so a text's vector depends on its batch (0.09
    apart seen), and the side contrast multiplies that by 4. The default int8-weights graph is
    batch-independent (2e-8), so the durations and lengths here take encode_text's vectors;
    the sampler's condition, where the difference shows most, takes this one."""
    from mlct.text.minilm import MiniLMEncoder
    from mlct.text.minilm_onnx import OnnxMiniLMEncoder
    from mlct.text.sides import SIDES_SUFFIX, contrast_sides

    encoder = generator.text_encoder
    if not isinstance(encoder, (MiniLMEncoder, OnnxMiniLMEncoder)):
        return torch.as_tensor(generator.encode_text([text])).float()
    text = plain_subject(text)  # as encode_text reads it
    with torch.no_grad():
        vector = encoder._embed([text])
        if encoder.name.endswith(SIDES_SUFFIX):
            vector = contrast_sides([text], vector, lambda mirrors: encoder._embed(mirrors[:1]))
    return torch.as_tensor(vector).float()  # (the onnx encoder's is an array)
