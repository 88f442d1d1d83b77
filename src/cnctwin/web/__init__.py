"""cnctwin in the browser: the live dashboard of a running twin (:mod:`cnctwin.web.server`,
:mod:`cnctwin.web.feed`) and the 3D stock view (:mod:`cnctwin.web.stock`).

Nothing here is imported by the rest of cnctwin unless a command is given ``--web``: the web
server (FastAPI, uvicorn) loads only then. See docs/dashboard.md.
"""
