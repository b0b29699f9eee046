"""``/docs`` (Swagger UI) and ``/redoc`` (ReDoc) with their scripts served by this server.

FastAPI's own pages load Swagger UI and ReDoc from a CDN, so offline they stay blank. The
``fastapi-offline`` package (MIT) ships both bundles; they are served from its folder under
``/api/docs-assets/`` (an ``/api`` path, so it never falls through to the dashboard's pages), and
the pages name no address outside this server (ReDoc without Google's fonts, Swagger UI without
its online validator).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from fastapi import FastAPI
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from starlette.requests import Request
from starlette.responses import HTMLResponse
from starlette.staticfiles import StaticFiles

__all__ = ["ASSETS_URL", "install_offline_docs"]

#: Where the Swagger UI and ReDoc bundles are served.
ASSETS_URL = "/api/docs-assets"


def _assets_dir() -> Path:
    return Path(str(resources.files("fastapi_offline") / "static"))


def install_offline_docs(
    app: FastAPI, *, docs_url: str = "/docs", redoc_url: str = "/redoc"
) -> None:
    """Add the two documentation pages and their assets to ``app`` (made with
    ``docs_url=None, redoc_url=None``)."""
    app.mount(ASSETS_URL, StaticFiles(directory=_assets_dir()), name="docs-assets")
    title = app.title

    def openapi_url(request: Request) -> str:
        return str(request.scope.get("root_path", "")) + (app.openapi_url or "/openapi.json")

    @app.get(docs_url, include_in_schema=False)
    async def swagger_ui(request: Request) -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url=openapi_url(request),
            title=f"{title} - Swagger UI",
            swagger_js_url=f"{ASSETS_URL}/swagger-ui-bundle.js",
            swagger_css_url=f"{ASSETS_URL}/swagger-ui.css",
            swagger_favicon_url=f"{ASSETS_URL}/favicon.png",
            # Swagger UI would ask validator.swagger.io for a badge: no call leaves the server.
            swagger_ui_parameters={"validatorUrl": None},
        )

    @app.get(redoc_url, include_in_schema=False)
    async def redoc(request: Request) -> HTMLResponse:
        return get_redoc_html(
            openapi_url=openapi_url(request),
            title=f"{title} - ReDoc",
            redoc_js_url=f"{ASSETS_URL}/redoc.standalone.js",
            redoc_favicon_url=f"{ASSETS_URL}/favicon.png",
            with_google_fonts=False,
        )
