"""Ray's token authentication, as Ray itself reads it (Ray >= 2.59).

A cluster started with token authentication (``RAY_AUTH_MODE=token``, or ``ray start``
finding a token already on the head) refuses every client that does not present its
token. Ray reads the token from, in this order, the ``RAY_AUTH_TOKEN`` environment
variable, the file ``RAY_AUTH_TOKEN_PATH`` names, and ``~/.ray/auth_token`` (``ray
get-auth-token`` prints it on the head). But a client joining an *explicit* address
(``--ray-address``, ``RAY_ADDRESS``) only presents it when ``RAY_AUTH_MODE=token`` is set:
Ray turns token mode on by itself only for a cluster it finds on this machine. So
:func:`use_token_auth` does what Ray does there for every address: when
``RAY_AUTH_MODE`` is unset and a token is found, token mode is turned on for this
process (a cluster without authentication accepts a client that presents one).

:func:`refused_message` is the error of a cluster that refused the client: the address,
where a token was looked for and what to set.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, MutableMapping
from pathlib import Path
from typing import Any

__all__ = ["MODE_ENV", "TOKEN_ENV", "TOKEN_PATH_ENV", "default_token_path", "refused_message",
           "token_source", "use_token_auth"]

MODE_ENV = "RAY_AUTH_MODE"  # "token" or "disabled"; unset: Ray's default
TOKEN_ENV = "RAY_AUTH_TOKEN"  # the token itself
TOKEN_PATH_ENV = "RAY_AUTH_TOKEN_PATH"  # a file holding it


def default_token_path() -> Path:
    """Ray's default token file, ``~/.ray/auth_token`` (Ray uses ``Path.home()``)."""
    return Path.home() / ".ray" / "auth_token"


def _readable_token(path: Path) -> bool:
    try:
        return bool(path.read_text(encoding="utf-8").strip())
    except (OSError, UnicodeDecodeError):
        return False


def token_source(environ: Mapping[str, str]) -> str:
    """Where Ray would read the token from (``RAY_AUTH_TOKEN``, ``RAY_AUTH_TOKEN_PATH
    (<file>)``, ``~/.ray/auth_token (<file>)``), or '' when there is none."""
    if environ.get(TOKEN_ENV, "").strip():
        return TOKEN_ENV
    named = environ.get(TOKEN_PATH_ENV, "").strip()
    if named:
        path = Path(named).expanduser()
        return f"{TOKEN_PATH_ENV} ({path})" if _readable_token(path) else ""
    path = default_token_path()
    return f"~/.ray/auth_token ({path})" if _readable_token(path) else ""


def use_token_auth(environ: MutableMapping[str, str] | None = None) -> str:
    """Turn Ray's token mode on for this process when ``RAY_AUTH_MODE`` is unset and a
    token is found (module doc); returns where the token comes from ('' if none). An
    explicit ``RAY_AUTH_MODE`` is respected."""
    env = os.environ if environ is None else environ
    source = token_source(env)
    if env.get(MODE_ENV) is None and source:
        env[MODE_ENV] = "token"
        if env is os.environ:
            import importlib

            raylet: Any = importlib.import_module("ray._raylet")  # compiled, no stubs
            raylet.Config.initialize("")  # Ray's own way of making the running process see it
    return source


def refused_message(shown: str, environ: Mapping[str, str], detail: str = "") -> str:
    """The error of a cluster that refused this client's token (``shown``: the address
    as :class:`suite.exec.ray.target.RayTarget` shows it)."""
    source = token_source(environ)
    mode = environ.get(MODE_ENV)
    sent = (f"the token from {source} was refused" if source and mode != "disabled" else
            f"{MODE_ENV}=disabled: no token was sent" if mode == "disabled" else
            f"no token was found ({TOKEN_ENV}, {TOKEN_PATH_ENV}, ~/.ray/auth_token)")
    why = f" ({detail})" if detail else ""
    return (f"{shown}: the Ray cluster refused this client's authentication{why}: {sent}. "
            f"Set {TOKEN_ENV} to the cluster's token (`ray get-auth-token` on its head "
            f"prints it), or {TOKEN_PATH_ENV} to a file holding it (docs/cluster.md)")
