"""The kit every paper's experiments are built with; no paper imports another, every paper imports this.

* :mod:`.model`: :class:`~.model.Profile`, :class:`~.model.Run`, :class:`~.model.Claim`,
  :class:`~.model.Experiment`, :class:`~.model.Paper`, an experiment's settings per scale (:func:`~.model.scaled`);
* :mod:`.planning`: frames, backends and their options, views, scenes, phantoms, truth runs;
* :mod:`.results`: reading an experiment's rows with errors that name what is missing;
* :mod:`.checks`: claims as small declarative checks (ratio, bound, band, growth);
* :mod:`.judging`: what every paper's claims share, once: a configuration's rows, a time ratio with its
  interval, a count over the views, a value with its interval in words, and one result of several
  labelled decisions that must all hold (``all_of``);
* :mod:`.words`: numbers, ratios and shares in words, for claims and pages;
* :mod:`.verdicts`: a claim's verdict (holds, fails, blocked, not measured);
* :mod:`.pages`: take-aways, linked tables, frames captions, the one difference scale.
"""
