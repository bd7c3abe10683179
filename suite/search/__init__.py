"""``hwyeval search``: find where a controller fails (docs/search.md).

* :mod:`suite.search.run`: the command, :func:`~suite.search.run.run_search` (the CLI
  only parses into its options); :mod:`suite.search.session`: one search into an output,
  its batches dispatched by the run layer (:mod:`suite.exec.build`);
  :mod:`suite.search.outcome`: its summary and exit code;
* :mod:`suite.search.space`: the ``[scenario.search]`` tables, checked; a drawn point
  built into a scenario by the catalog loader (or refused);
* :mod:`suite.search.loop`: the ask-and-tell loop over Optuna, batches on an executor;
* :mod:`suite.search.shrink`: per failure mode, the failing point nearest the nominal;
* :mod:`suite.search.found`: ``found.toml`` and ``search.csv`` (its rows:
  :mod:`reports.record.search`);
* :mod:`suite.search.compare`: the search against random sampling, runs to the first
  failure and distinct failure modes.
"""
