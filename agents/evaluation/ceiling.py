"""The certified ceiling beside a results table: the share of its episodes' starts that a
committed certificate (:mod:`agents.artifacts.certificates`, written by
:mod:`agents.certification.certify`) proves some controller can bring to the scene's end."""

from __future__ import annotations

from pathlib import Path

from agents.artifacts.certificates import (
    CERTIFICATES_DIR,
    FEASIBLE,
    NOT_RECOVERABLE,
    Certificate,
    CertificateStart,
    committed_certificate,
)


def _covered(certificate: Certificate, episodes: int, seed: int) -> list[CertificateStart] | None:
    """The starts of episodes ``seed .. seed + episodes - 1``, or None when the
    certificate does not cover all of them."""
    by_seed = certificate.by_seed()
    wanted = range(seed, seed + episodes)
    if any(episode_seed not in by_seed for episode_seed in wanted):
        return None
    return [by_seed[episode_seed] for episode_seed in wanted]


def status_count(
    status: str,
    env_id: str,
    n_trailers: int,
    episodes: int,
    seed: int,
    directory: Path = CERTIFICATES_DIR,
    randomize: str | None = None,
) -> int | None:
    """How many starts of episodes ``seed .. seed + episodes - 1`` the committed
    certificate (of the randomisation preset ``randomize``; None: nominal physics) gives
    ``status``, or None when none covers all of them."""
    certificate = committed_certificate(env_id, n_trailers, directory, randomize)
    starts = None if certificate is None else _covered(certificate, episodes, seed)
    if starts is None:
        return None
    return sum(start.status == status for start in starts)


def ceiling_fraction(
    env_id: str,
    n_trailers: int,
    episodes: int,
    seed: int,
    directory: Path = CERTIFICATES_DIR,
    randomize: str | None = None,
) -> float | None:
    """The certified share of the starts of episodes ``seed .. seed + episodes - 1``, or None
    when no committed certificate covers all of them (the leaderboard's ceiling line)."""
    feasible = status_count(FEASIBLE, env_id, n_trailers, episodes, seed, directory, randomize)
    return None if feasible is None else feasible / episodes


def ceiling_note(
    env_id: str, n_trailers: int, episodes: int, seed: int, directory: Path = CERTIFICATES_DIR
) -> str:
    """The ceiling line under a results table: the certified share of the episodes' starts,
    and who found their records (the planner, or a witness:
    :mod:`agents.certification.witnesses`).

    Only starts the certificate covers are counted; episodes outside it say so.
    """
    certificate = committed_certificate(env_id, n_trailers, directory)
    if certificate is None:
        return "ceiling: not certified (no planner for this scene, or `agents.certify` not run)"
    starts = _covered(certificate, episodes, seed)
    if starts is None:
        first, last = certificate.seeds
        return (
            f"ceiling: certified on seeds {first}-{last} "
            f"({100 * certificate.ceiling:.0f}% feasible), not on these episodes"
        )
    feasible = sum(start.status == FEASIBLE for start in starts)
    unrecoverable = sum(start.status == NOT_RECOVERABLE for start in starts)
    counts: dict[str, int] = {}
    for start in certificate.starts:
        source = certificate.source_of(start) if seed <= start.seed < seed + episodes else None
        if source is not None:
            counts[source] = counts.get(source, 0) + 1
    planner = certificate.planner.label
    order = sorted(counts.items(), key=lambda item: (item[0] != planner, -item[1], item[0]))
    by_source = ", ".join(f"{source} {count}" for source, count in order)
    opened = episodes - feasible - unrecoverable
    if not certificate.screen.is_applied:
        return (
            f"ceiling: {feasible}/{episodes} starts certified feasible (action records "
            f"replayed open-loop to the goal, by source: {by_source}; `python -m "
            f"agents.certify`); {opened} open (no screen for a goal)"
        )
    return (
        f"ceiling: {feasible}/{episodes} starts certified feasible (action records replayed "
        f"open-loop, by source: {by_source}; `python -m agents.certify`); {unrecoverable} not "
        f"recoverable (screen), {opened} open"
    )


__all__ = ["ceiling_fraction", "ceiling_note"]
