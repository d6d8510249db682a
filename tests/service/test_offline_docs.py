"""`/docs` works without the internet: Swagger UI's files are served by the API from an installed package."""

from __future__ import annotations

import re

from fastapi.testclient import TestClient

ASSET = re.compile(r"""(?:src|href)\s*=\s*["']([^"']+)["']""")


def test_docs_page_loads_swagger_ui_from_the_service_itself(client: TestClient) -> None:
    page = client.get("/docs")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assets = ASSET.findall(page.text)
    assert any(a.endswith("swagger-ui-bundle.js") for a in assets)
    assert any(a.endswith("swagger-ui.css") for a in assets)
    assert not re.search(r"https?://|//[a-z0-9.-]+\.[a-z]{2,}/|cdn", page.text, re.IGNORECASE), page.text
    for url in assets:
        assert url.startswith("/"), url
        response = client.get(url)
        assert response.status_code == 200, url
        assert len(response.content) > 100, url
    assert client.get("/openapi.json").status_code == 200
    assert "SwaggerUIBundle" in client.get(next(a for a in assets if a.endswith(".js"))).text


def test_no_docs_page_points_at_a_cdn(client: TestClient) -> None:
    assert client.get("/redoc").status_code == 404  # ReDoc ships no offline files: not offered
    assert client.get("/docs/oauth2-redirect").status_code == 200
