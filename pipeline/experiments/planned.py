"""Papers whose backends or experiments do not exist yet, and what each needs.

The report lists them (with the reason) so a reader sees what is missing rather than a silent gap.
:func:`planned` computes the list from each paper's declaration
(:class:`~pipeline.experiments.kit.model.Paper`) against the backend registry, so a paper drops out
of it on its own once its backends are registered and it has experiments.
"""


def planned(backend_names, papers):
    """Rows ``{paper, title, reason, needs}`` for every paper not reproduced yet.

    Parameters
    ----------
    backend_names : iterable of str
        Registered backends (``renderers.names()``).
    papers : iterable of Paper
        Every paper (:func:`pipeline.experiments.papers`); the project's own studies (no technique)
        are not listed.
    """
    registered = set(backend_names)
    rows = []
    for paper in papers:
        if paper.technique is None:
            continue
        missing = [b for b in paper.backends if b not in registered]
        if not missing and paper.experiments:
            continue
        if missing:
            reason, needs = "backend not implemented yet", f"{', '.join(missing)}: {paper.needs}"
        else:
            reason, needs = "experiments not written yet", f"experiments for {', '.join(paper.backends)} ({paper.needs})"
        rows.append({"paper": paper.id, "title": paper.title, "reason": reason, "needs": needs})
    return rows


def techniques(papers):
    """``{paper id: backend}``: the backend whose frames are each paper's technique."""
    return {paper.id: paper.technique for paper in papers if paper.technique}
