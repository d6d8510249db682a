"""The FastAPI application factory (run with ``uvicorn --factory service.app:create_app``)."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse
from sqlalchemy import text

from service.db import make_engine, make_sessionmaker, migrate
from service.idempotency import Idempotency
from service.limits import BodySizeLimit
from service.openapi import install_openapi
from service.problems import install_handlers
from service.queue import CeleryJobQueue
from service.routes import comparisons, demonstrations, demonstrators, jobs, mdps, recordings, rewards, tasks
from service.settings import Settings, get_settings

DESCRIPTION = """Meta inverse reinforcement learning as a service: upload MDPs and one demonstrator's
demonstrations of several tasks; learn every task's reward and the demonstrator's shared baseline reward.

Every `/v1` route needs `Authorization: Bearer <api key>` (`metairl keys create --lab NAME`). Errors are
RFC 9457 `application/problem+json`. POSTs accept an `Idempotency-Key` header."""

TAGS = [
    {"name": "mdps", "description": "State spaces, actions, transitions and features (API.md §1)."},
    {
        "name": "demonstrators",
        "description": "People, robots or sessions with a shared baseline reward (§2).",
    },
    {
        "name": "tasks",
        "description": "Tasks of a demonstrator, each in one MDP, with optional true rewards (§3).",
    },
    {"name": "demonstrations", "description": "Trajectories of a task, checked against its MDP (§4)."},
    {"name": "jobs", "description": "Fits run by workers: submit, follow progress, cancel (§5)."},
    {"name": "rewards", "description": "Learned rewards, value functions and policies of a job (§6)."},
    {"name": "comparisons", "description": "Pearson, Spearman and EPIC distance between rewards (§7)."},
    {"name": "health", "description": "Liveness and readiness probes (no authentication)."},
]

UNAVAILABLE = {"status": "unavailable", "detail": "database unreachable: OperationalError"}


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the app: migrate the database, keep sessionmaker and settings on `app.state`, add routes."""
    settings = settings or get_settings()
    engine = make_engine(settings)
    migrate(engine)

    @asynccontextmanager
    async def lifespan(_app: FastAPI) -> AsyncIterator[None]:
        yield
        engine.dispose()

    app = FastAPI(
        title="metairl",
        version="1.0.0",
        description=DESCRIPTION,
        openapi_tags=TAGS,
        lifespan=lifespan,
    )
    app.state.settings = settings
    app.state.engine = engine
    app.state.sessionmaker = make_sessionmaker(engine)
    app.state.job_queue = CeleryJobQueue(settings)
    install_handlers(app)
    app.add_middleware(Idempotency, settings=settings)
    app.add_middleware(BodySizeLimit, settings=settings)
    for module in (mdps, demonstrators, tasks, demonstrations, recordings, jobs, rewards, comparisons):
        app.include_router(module.router, prefix="/v1")

    install_openapi(app)

    @app.get("/healthz", tags=["health"], summary="The process is up", responses=_example({"status": "ok"}))
    def healthz() -> dict[str, str]:
        """Liveness: answers while the process runs."""
        return {"status": "ok"}

    @app.get(
        "/readyz",
        tags=["health"],
        summary="The database is reachable",
        responses=_example({"status": "ok"})
        | {503: {"description": "The database cannot be reached.", **_example(UNAVAILABLE)[200]}},
    )
    def readyz(request: Request) -> JSONResponse:
        """Readiness: 200 when a trivial query succeeds, 503 otherwise."""
        try:
            with request.app.state.engine.connect() as connection:
                connection.execute(text("SELECT 1"))
        except Exception as exc:
            return JSONResponse(
                UNAVAILABLE | {"detail": f"database unreachable: {type(exc).__name__}"},
                status_code=503,
            )
        return JSONResponse({"status": "ok"})

    return app


def _example(body: dict[str, str]) -> dict[int | str, dict[str, Any]]:
    """An OpenAPI `responses` entry documenting a 200 JSON response by an example."""
    return {200: {"content": {"application/json": {"example": body}}}}
