# metairl: one image for the API and the worker (docker-compose.yml picks the command).
# CPU-only torch is installed first from the PyTorch CPU index, so the project install never pulls CUDA wheels.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    METAIRL_DATA_DIR=/data

WORKDIR /app
RUN pip install --index-url https://download.pytorch.org/whl/cpu "torch==2.13.0"

COPY pyproject.toml README.md ./
COPY metairl_engine ./metairl_engine
COPY service ./service
COPY worker ./worker
COPY metairl_client ./metairl_client
COPY metairl_cli ./metairl_cli
RUN pip install . \
    && useradd --create-home --uid 1000 metairl \
    && mkdir -p /data && chown metairl /data

USER metairl
EXPOSE 8000
# The API migrates the database on start (an advisory lock makes concurrent starts safe). uvloop sets
# TCP_NODELAY on every connection (without it keep-alive responses stall on delayed ACKs); uvicorn reads the
# number of API processes from WEB_CONCURRENCY (default 1: set it to the container's cores).
CMD ["uvicorn", "--factory", "service.api.app:create_app", "--host", "0.0.0.0", "--port", "8000", "--loop", "uvloop", "--http", "httptools"]
