"""The FastAPI application factory (run with ``uvicorn --factory service.api.app:create_app``)."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse
from sqlalchemy import text
from sqlalchemy.ext.asyncio import AsyncEngine

from service.api.async_db import async_engine
from service.api.auth import KeyCache
from service.api.docs import install_docs
from service.api.idempotency import Idempotency
from service.api.input_guard import InputGuard
from service.api.limits import BodySizeLimit
from service.api.memory import ReturnMemory
from service.api.openapi import install_openapi
from service.api.ratelimit import RateLimit
from service.api.routes import (
    comparisons,
    demonstrations,
    demonstrators,
    jobs,
    mdps,
    motion,
    recordings,
    rewards,
    sway,
    tasks,
    ui,
    webhooks,
)
from service.api.sse import StreamSlots
from service.jobs.queue import CeleryJobQueue
from service.problems import install_handlers
from service.settings import Settings, get_settings
from service.store.db import make_engine, make_sessionmaker, migrate

DESCRIPTION = """Meta inverse reinforcement learning as a service: upload MDPs and one demonstrator's
demonstrations of several tasks; learn every task's reward and the demonstrator's shared baseline reward.

Every `/v1` route needs `Authorization: Bearer <api key>` (`metairl keys create --lab NAME`). Errors are
RFC 9457 `application/problem+json`. POSTs accept an `Idempotency-Key` header."""

TAGS = [
    {"name": "mdps", "description": "State spaces, actions, transitions and features."},
    {
        "name": "demonstrators",
        "description": "People, robots or sessions with a shared baseline reward.",
    },
    {
        "name": "tasks",
        "description": "Tasks of a demonstrator, each in one MDP, with optional true rewards.",
    },
    {"name": "demonstrations", "description": "Trajectories of a task, checked against its MDP."},
    {"name": "jobs", "description": "Fits run by workers: submit, follow progress, cancel."},
    {"name": "rewards", "description": "Learned rewards, value functions and policies of a job."},
    {"name": "comparisons", "description": "Pearson, Spearman and EPIC distance between rewards."},
    {
        "name": "motion",
        "description": "Kinematic readout of centre-of-pressure recordings per direction, and session comparisons.",
    },
    {"name": "webhooks", "description": "URLs called, signed, when a lab's jobs end."},
    {"name": "health", "description": "Liveness and readiness probes (no authentication)."},
]

UNAVAILABLE = {"status": "unavailable", "detail": "database unreachable: OperationalError"}


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the app: migrate the database, keep sessionmaker and settings on `app.state`, add routes (the
    lifespan adds the async engine of the hot read routes)."""
    settings = settings or get_settings()
    engine = make_engine(settings)
    migrate(engine)

    @asynccontextmanager
    async def lifespan(_app: FastAPI) -> AsyncIterator[dict[str, AsyncEngine]]:
        """Per process: the async engine of the hot read routes (`service.api.async_db`) as lifespan state;
        at shutdown both engines are disposed."""
        async with async_engine(settings) as state:
            yield state
        engine.dispose()

    app = FastAPI(
        title="metairl",
        version="1.0.0",
        description=DESCRIPTION,
        openapi_tags=TAGS,
        lifespan=lifespan,
        docs_url=None,  # `install_docs` serves Swagger UI from the installed package, not a CDN
        redoc_url=None,
    )
    app.state.settings = settings
    app.state.engine = engine
    app.state.sessionmaker = make_sessionmaker(engine)
    # The key check reads one row (and notes the key's use at most once a minute): statements that commit on
    # their own spare it the BEGIN and ROLLBACK round trips of a transaction on every request.
    app.state.key_sessionmaker = make_sessionmaker(engine.execution_options(isolation_level="AUTOCOMMIT"))
    app.state.key_cache = KeyCache(settings.api_key_cache_s)
    app.state.job_queue = CeleryJobQueue(settings)
    app.state.stream_slots = StreamSlots(settings.events_max_streams_per_key)
    install_handlers(app)
    app.add_middleware(Idempotency, settings=settings)
    app.add_middleware(ReturnMemory)
    app.add_middleware(InputGuard)  # a NUL or too-deep JSON never reaches the key's record or the database
    app.add_middleware(BodySizeLimit, settings=settings)
    app.add_middleware(RateLimit, settings=settings)  # outermost: a refusal costs no body and no database

    # The probes first: the router tries routes in order, and an orchestrator polls them most often.
    @app.get("/healthz", tags=["health"], summary="The process is up", responses=_example({"status": "ok"}))
    async def healthz() -> JSONResponse:
        """Liveness: answers while the process runs (on the event loop: no thread, no validation)."""
        return JSONResponse({"status": "ok"})

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

    for module in (
        mdps,
        demonstrators,
        tasks,
        demonstrations,
        recordings,
        jobs,
        rewards,
        comparisons,
        motion,
        sway,
        webhooks,
    ):
        app.include_router(module.router, prefix="/v1")

    app.include_router(ui.router)  # GET /ui: the dashboard (not in the OpenAPI document)
    install_openapi(app)
    install_docs(app)

    return app


def _example(body: dict[str, str]) -> dict[int | str, dict[str, Any]]:
    """An OpenAPI `responses` entry documenting a 200 JSON response by an example."""
    return {200: {"content": {"application/json": {"example": body}}}}
