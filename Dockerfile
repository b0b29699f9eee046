# One image for the BioPlan API server and for Dask scheduler/workers (docker/compose.yaml).
#
#   docker build -t bioplan .
#   docker run --rm -p 127.0.0.1:8000:8000 -e BIOPLAN_HOST=0.0.0.0 \
#       -e BIOPLAN_API_TOKEN=change-me -v bioplan-data:/data bioplan
#
# The server refuses to bind to 0.0.0.0 without BIOPLAN_API_TOKEN.
FROM python:3.11-slim-bookworm

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1

# libgomp: OpenMP runtime used by the numerical wheels; curl-free health check uses Python.
RUN apt-get update \
    && apt-get install -y --no-install-recommends libgomp1 \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --create-home --uid 1000 bioplan \
    && mkdir -p /data \
    && chown bioplan /data

WORKDIR /srv/bioplan

# Dependencies first (cached while only the code changes).
COPY pyproject.toml README.md ./
RUN mkdir -p app && touch app/__init__.py \
    && pip install . "psycopg[binary]>=3.2" \
    && pip uninstall -y bioplan

# The code. Installed editable so the Alembic migrations beside `app/` are found at run time.
COPY alembic.ini ./
COPY migrations ./migrations
COPY app ./app
RUN pip install --no-deps -e . \
    && python -c "import app.main, app.jobs.tasks, distributed"

USER bioplan
ENV BIOPLAN_DATA_DIR=/data \
    BIOPLAN_PORT=8000
VOLUME ["/data"]
EXPOSE 8000

HEALTHCHECK --interval=30s --timeout=5s --start-period=30s --retries=3 \
    CMD python -c "import urllib.request, os; urllib.request.urlopen('http://127.0.0.1:' + os.environ.get('BIOPLAN_PORT', '8000') + '/api/health', timeout=4)"

# `bioplan serve` runs `alembic upgrade head`, then uvicorn with one worker process.
CMD ["bioplan", "serve"]
