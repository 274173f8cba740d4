"""The Model box in a user's words: what arm, how it denoises, how well it learned, and its student.

A learner reads "a 4-link arm, denoised in 80 steps, half its poses within 0.007 bone lengths" where the
box used to say "N = 4, film, cossin, p95 (ddpm raw, K=1)". The technical names stay, in brackets, for
those who look for them; the Words folder defines each. No viser here.
"""

from __future__ import annotations

REPRESENTATION_WORDS = {
    "cossin": "each angle as (cos, sin), so -180° and 180° are one value",
    "angle": "each angle divided by π, as the paper does",
}
DENOISER_WORDS = {
    "film": "a small MLP that reads t and the target through FiLM",
    "paper": "the paper's transformer",
    "mlp": "a plain MLP",
}
SAMPLER_WORDS = {"ddpm raw, K=1": "DDPM, one sample per target, no polish"}


def model_words(num_links: int, lengths, num_timesteps: int, metadata: dict, student_steps: int | None = None) -> str:
    """The planar Model box: `student_steps` the folded-in student's steps (None: the model has no student)."""
    model, metrics = metadata.get("model", {}), metadata.get("metrics", {})
    shown_lengths = ", ".join(f"{length:g}" for length in lengths)
    lines = [
        f"**A {num_links}-link planar arm** (N = {num_links}), bones {shown_lengths} long; it reaches up to "
        f"{sum(lengths):g} from its base.",
        f"**Denoising**: T = {num_timesteps} steps from pure noise to a pose "
        f"({model.get('schedule', {}).get('kind', '?')} noise schedule).",
    ]
    representation, denoiser = model.get("representation", "?"), model.get("denoiser", {}).get("kind", "?")
    lines.append(
        f"**The network**: {DENOISER_WORDS.get(denoiser, denoiser)} ({denoiser}); it sees "
        f"{REPRESENTATION_WORDS.get(representation, representation)} ({representation})."
    )
    if "tip_error_median" in metrics:
        sampler = str(metrics.get("sampler", ""))
        how = SAMPLER_WORDS.get(sampler, sampler)
        lines.append(
            f"**How well it learned** ({metrics.get('step', '?')} training steps): on "
            f"{metrics.get('eval_targets', 'its')} random targets, half the tips land within "
            f"{metrics['tip_error_median']:.4f} bone lengths of the target, 95 in 100 within "
            f"{metrics.get('tip_error_p95', float('nan')):.4f} (p95; {how})."
        )
    if student_steps is not None:
        lines.append(
            f"**Its student**: a copy distilled to land in {student_steps} steps where the full DDPM lands: "
            "the sampler “student”."
        )
    return "  \n".join(lines)
