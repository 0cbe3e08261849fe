"""The editor page served from this machine: ``fpiwarp preview IMAGE --web``.

:class:`PageServer` serves one :class:`~fpiwarp.widget.session.Session` on
127.0.0.1 at a free port. Every request for the page or the session's data must carry the session's
token (``?token=`` in the page's URL, which the page passes on); the page
and its scripts come from this package (``static/``, served to anyone who
asks: they are fpiwarp's own files) and its Content-Security-Policy
lets it load nothing from anywhere else.

Routes: ``/`` the page; ``/static/NAME`` its script and style;
``/api/state`` (GET) the frame's state; ``/api/image`` (GET) the display
texture's pixels (meta in ``X-Fpiwarp-Image``); ``/api/program?key=K`` (GET)
a program's GLSL ES texts; ``/api/message`` (POST, JSON) a page message,
answered with the new state.
"""

import json
import secrets
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from urllib.parse import parse_qs, urlparse

from ..errors import FpiwarpError

#: The page's files (package data of fpiwarp.widget).
STATIC = {"editor.js": "text/javascript", "page.js": "text/javascript", "editor.css": "text/css"}
PAGE = "page.html"
#: Nothing from outside this server; WebGL needs no more.
CSP = ("default-src 'none'; script-src 'self'; style-src 'self'; connect-src 'self'; img-src 'self' data: blob:; "
       "base-uri 'none'; form-action 'none'; frame-ancestors 'none'")


def static_text(name):
    """The text of one of the page's files."""
    return resources.files("fpiwarp.widget").joinpath("static", name).read_text(encoding="utf-8")


class PageServer:
    """Serve ``session`` on 127.0.0.1 (``port`` 0: a free one).

    Use ``url`` (with the token) to open the page; ``start`` serves from a
    thread, ``serve_forever`` from the caller's; ``close`` stops. Calls into
    the session are serialised by ``lock``.
    """

    def __init__(self, session, *, port=0, token=None):
        self.session = session
        self.token = token or secrets.token_urlsafe(18)
        self.lock = threading.Lock()
        self.errors = []  # messages the server refused, for the caller to see
        self.httpd = ThreadingHTTPServer(("127.0.0.1", port), _handler(self))
        self.httpd.daemon_threads = True
        self._thread = None

    @property
    def port(self):
        return self.httpd.server_address[1]

    @property
    def url(self):
        return f"http://127.0.0.1:{self.port}/?token={self.token}"

    def start(self):
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="fpiwarp-page", daemon=True)
        self._thread.start()
        return self

    def serve_forever(self):
        self.httpd.serve_forever()

    def close(self):
        if self._thread is not None:
            self.httpd.shutdown()
            self._thread.join(5)
        self.httpd.server_close()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.close()


def _handler(server):
    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args):  # quiet: the CLI prints the URL and what it wrote
            pass

        def _send(self, status, body, content_type, headers=()):
            data = body.encode("utf-8") if isinstance(body, str) else body
            self.send_response(status)
            self.send_header("Content-Type", content_type)
            self.send_header("Content-Length", str(len(data)))
            self.send_header("Cache-Control", "no-store")
            self.send_header("Content-Security-Policy", CSP)
            self.send_header("X-Content-Type-Options", "nosniff")
            self.send_header("Referrer-Policy", "no-referrer")
            for k, v in headers:
                self.send_header(k, v)
            self.end_headers()
            self.wfile.write(data)

        def _json(self, obj, status=HTTPStatus.OK):
            self._send(status, json.dumps(obj, allow_nan=False), "application/json")

        def _authorised(self, query):
            given = self.headers.get("X-Fpiwarp-Token") or (query.get("token") or [""])[0]
            if secrets.compare_digest(given, server.token):
                return True
            self._send(HTTPStatus.FORBIDDEN, "wrong or missing token", "text/plain; charset=utf-8")
            return False

        def do_GET(self):
            url = urlparse(self.path)
            query = parse_qs(url.query)
            path = url.path
            if path.startswith("/static/") and path[8:] in STATIC:  # the package's own files: no secret
                return self._send(HTTPStatus.OK, static_text(path[8:]), STATIC[path[8:]] + "; charset=utf-8")
            if not self._authorised(query):
                return
            if path == "/":
                return self._send(HTTPStatus.OK, static_text(PAGE), "text/html; charset=utf-8")
            with server.lock:
                if path == "/api/state":
                    return self._json(server.session.state())
                if path == "/api/image":
                    meta, data = server.session.image_payload()
                    return self._send(HTTPStatus.OK, data, "application/octet-stream",
                                      [("X-Fpiwarp-Image", json.dumps(meta))])
                if path == "/api/program":
                    program = server.session.programs.get((query.get("key") or [""])[0])
                    if program is not None:
                        return self._json(program)
            self._send(HTTPStatus.NOT_FOUND, "not found", "text/plain; charset=utf-8")

        def do_POST(self):
            url = urlparse(self.path)
            if not self._authorised(parse_qs(url.query)):
                return
            if url.path != "/api/message":
                return self._send(HTTPStatus.NOT_FOUND, "not found", "text/plain; charset=utf-8")
            try:
                length = int(self.headers.get("Content-Length", "0"))
                msg = json.loads(self.rfile.read(min(length, 1 << 20)) or b"null")
                with server.lock:
                    server.session.handle(msg)
                    state = server.session.state()
            except (FpiwarpError, ValueError, KeyError, TypeError) as exc:
                text = " ".join(str(exc).split()) or type(exc).__name__
                server.errors.append(text)
                return self._json({"error": text}, HTTPStatus.BAD_REQUEST)
            self._json(state)

    return Handler
