"""The kit every paper's experiments are built with; no paper imports another, every paper imports this.

* :mod:`.model`: :class:`~.model.Profile`, :class:`~.model.Run`, :class:`~.model.Claim`,
  :class:`~.model.Experiment`, :class:`~.model.Paper`;
* :mod:`.planning`: frames, backends and their options, views, scenes, phantoms, truth runs;
* :mod:`.results`: reading an experiment's rows with errors that name what is missing;
* :mod:`.checks`: claims as small declarative checks (ratio, bound, band, growth), and one result of
  several labelled decisions that must all hold (``every``, with ``decision_words``);
* :mod:`.verdicts`: a claim's verdict (holds, fails, blocked, not measured);
* :mod:`.pages`: take-aways, linked tables, numbers in words, the one difference scale.
"""
