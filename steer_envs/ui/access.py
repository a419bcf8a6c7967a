"""Who may use a steer-ui server: the ``Host`` names it answers to and the pages whose WebSocket it accepts.

A server that moves a (simulated, one day a real) robot must not be driven
by whatever web page its user happens to open. Two checks keep it local:

* **Host**: requests must name the server as one of :func:`allowed_hosts`
  (this machine's names, plus the bound address or names the user allows):
  a DNS-rebinding page reaches ``127.0.0.1`` under a name of its own and is
  refused;
* **Origin**: a WebSocket must come from the page the server itself serves
  (:func:`same_origin`): another site's script, or a ``null`` origin, is
  refused. A client that sends no ``Origin`` (a script, not a browser) is let in.

>>> allowed_hosts("127.0.0.1")
('127.0.0.1', 'localhost', '::1')
>>> allowed_hosts("0.0.0.0", ["robot-pc.lan"])
('127.0.0.1', 'localhost', '::1', 'robot-pc.lan')
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["ANY_INTERFACE", "LOCAL_HOSTS", "allowed_hosts", "is_local", "same_origin"]

#: the names of this machine a local server answers to
LOCAL_HOSTS: tuple[str, ...] = ("127.0.0.1", "localhost", "::1")
#: bind addresses that listen on every interface (no name of their own to check a Host against)
ANY_INTERFACE: tuple[str, ...] = ("0.0.0.0", "::")


def is_local(host: str) -> bool:
    """Whether binding to ``host`` keeps the server on this machine."""
    return host in LOCAL_HOSTS


def allowed_hosts(bind: str, extra: Iterable[str] = ()) -> tuple[str, ...]:
    """The ``Host`` names a server bound to ``bind`` accepts: this machine's, ``bind`` itself, and ``extra``."""
    names = [*LOCAL_HOSTS]
    for name in (bind, *extra):
        name = name.strip().strip("[]").lower()
        if name and name not in ANY_INTERFACE and name not in names:
            names.append(name)
    return tuple(names)


def same_origin(origin: str | None, host: str | None) -> bool:
    """Whether a WebSocket's ``Origin`` is the page's own: ``http(s)://`` + the request's ``Host``.

    >>> same_origin("http://127.0.0.1:8765", "127.0.0.1:8765"), same_origin("http://evil.example", "127.0.0.1:8765")
    (True, False)
    >>> same_origin(None, "localhost:8765"), same_origin("null", "localhost:8765")
    (True, False)
    """
    if origin is None:
        return True
    if not host:
        return False
    return origin.lower() in (f"http://{host.lower()}", f"https://{host.lower()}")
