"""``hwyeval search``: find where a controller fails (docs/search.md).

* :mod:`suite.search.space`: the ``[scenario.search]`` tables, checked; a drawn point
  built into a scenario by the catalog loader (or refused);
* :mod:`suite.search.loop`: the ask-and-tell loop over Optuna, batches on an executor;
* :mod:`suite.search.shrink`: per failure mode, the failing point nearest the nominal;
* :mod:`suite.search.found`: ``found.toml`` and ``search.csv``;
* :mod:`suite.search.compare`: the search against random sampling, runs to the first
  failure and distinct failure modes.
"""
