"""`GET /ui`: the dashboard, one HTML page with its script and style, served from files in the package.

The page (plain JavaScript, no build step, nothing from a CDN) talks to `/v1` with the API key the person
pastes; it is kept in the browser's session storage. These routes need no key and are left out of the
OpenAPI document (docs/api.md, "The dashboard", describes them).
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, HTTPException
from fastapi.responses import FileResponse

STATIC = Path(__file__).resolve().parent.parent / "static" / "ui"
ASSETS = {"app.js": "text/javascript", "app.css": "text/css"}
HEADERS = {
    "Cache-Control": "no-cache",
    "X-Content-Type-Options": "nosniff",
    # Only this origin's script and style; heatmaps are shown from blob: URLs made by the script.
    "Content-Security-Policy": "default-src 'self'; img-src 'self' blob: data:; object-src 'none'; "
    "base-uri 'none'; frame-ancestors 'none'",
}

router = APIRouter(include_in_schema=False)


@router.get("/ui")
def dashboard() -> FileResponse:
    """The dashboard page."""
    return FileResponse(STATIC / "index.html", media_type="text/html", headers=HEADERS)


@router.get("/ui/{name}")
def asset(name: str) -> FileResponse:
    """The page's script or style sheet (nothing else under /ui is served)."""
    if name not in ASSETS:
        raise HTTPException(status_code=404, detail=f"no such file: /ui/{name}")
    return FileResponse(STATIC / name, media_type=ASSETS[name], headers=HEADERS)
