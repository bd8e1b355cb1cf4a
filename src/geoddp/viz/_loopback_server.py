"""meshcat's ZMQ/websocket bridge with its HTTP server bound to 127.0.0.1 only.

meshcat 0.3.2 binds ZMQ to 127.0.0.1 but calls ``tornado.web.Application.listen(port)``
without an address, which listens on every interface. This script is run as a subprocess
*by file path* (it imports only meshcat and tornado, not geoddp), and prints the same two
lines as ``python -m meshcat.servers.zmqserver``: ``zmq_url=...`` then ``web_url=...``.
"""
from __future__ import annotations

import os
import threading
import time

import tornado.web
from meshcat.servers import zmqserver as zs

LOOPBACK = "127.0.0.1"


class _LoopbackApplication(tornado.web.Application):
    def listen(self, port, address=None, **kwargs):  # type: ignore[override]
        return super().listen(port, address=LOOPBACK if address is None else address, **kwargs)


class LoopbackBridge(zs.ZMQWebSocketBridge):
    def make_app(self):
        # Same routes as meshcat's make_app, only the application class differs.
        return _LoopbackApplication([
            (r"/static/(.*)", zs.StaticFileHandlerNoCache,
             {"path": zs.VIEWER_ROOT, "default_filename": zs.VIEWER_HTML}),
            (r"/", zs.WebSocketHandler, {"bridge": self}),
        ])


def _exit_with_parent(parent: int) -> None:
    """Exit when the process that started this server is gone (killed with SIGKILL, crashed):
    the server runs in its own session, so no signal reaches it then (clean exits)."""
    while True:
        time.sleep(0.5)
        if os.getppid() != parent:
            os._exit(0)


def main() -> None:
    threading.Thread(target=_exit_with_parent, args=(os.getppid(),), daemon=True).start()
    bridge = LoopbackBridge(host=LOOPBACK)
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass


if __name__ == "__main__":
    main()
