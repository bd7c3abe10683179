"""The forkserver's preload (:data:`suite.exec.forkserver.PRELOAD`): importing this module
calls :func:`suite.exec.prepare.prepare_process`, and that is its only job.

It is the one module of hwyeval that acts when imported, because multiprocessing's
forkserver preload takes module names (``set_forkserver_preload``), not a function to
call. Nothing else imports it: every other process that needs the same preparation (a
Ray actor, the bench's probes, the tests) calls :func:`~suite.exec.prepare.prepare_process`
itself.
"""

from __future__ import annotations

from suite.exec.prepare import prepare_process

prepare_process()
