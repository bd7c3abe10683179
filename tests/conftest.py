"""Test configuration: the markers (``--strict-markers`` is on, pyproject's addopts) and
the fast lane.

Markers:

* ``sumo``: needs a real libsumo simulation (an integration test);
* ``slow``: takes more than ~1.5 s on a 2-core machine; ``pytest -m "not slow"`` is the
  fast lane (under 3 minutes), plain ``pytest`` runs everything;
* ``browser``: needs headless Chromium.

Slow is marked at the test: ``@pytest.mark.slow`` on the function, or ``pytestmark`` for
a file whose tests all are (setup + call + teardown > 1.5 s, all parametrisations summed,
as ``pytest --durations=0`` measures it). Re-measure after adding heavy tests and mark
them where they are written; there is no list here.

Fixtures:

* ``plain_net`` (session): builds a net with SUMO's netconvert from plain XML
  (:func:`tests.plain_nets.build_plain_net`, the same inputs once per session); the test
  is skipped when SUMO is not installed.

Unit tests assert behaviour, not wall-clock time: timing belongs in the bench
(``hwyeval bench``).
"""

from __future__ import annotations

import pytest

from tests.plain_nets import PlainNet, build_plain_net, netconvert_exe

MARKERS = {
    "sumo": "needs a real libsumo simulation (integration test)",
    "slow": "takes more than ~1.5 s (deselect with -m 'not slow': the fast lane)",
    "browser": "needs headless Chromium",
    "serial": "races processes and signals against the clock: the test command runs these "
              "alone, after the two parallel lanes",
}


def pytest_configure(config: pytest.Config) -> None:
    for name, doc in MARKERS.items():
        config.addinivalue_line("markers", f"{name}: {doc}")


@pytest.fixture(scope="session")
def plain_net() -> PlainNet:
    netconvert_exe()  # skips every test using the fixture when SUMO is absent
    return build_plain_net
