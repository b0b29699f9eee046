# One image for the BioPlan API server and for Dask scheduler/workers (docker/compose.yaml).
#
#   docker build -t bioplan .
#   docker run --rm -p 127.0.0.1:8000:8000 -p 127.0.0.1:8080:8080 \
#       -e BIOPLAN_HOST=0.0.0.0 -e BIOPLAN_VIEWER_HOST=0.0.0.0 \
#       -e BIOPLAN_API_TOKEN=change-me -v bioplan-data:/data bioplan
#
# The server refuses to bind to 0.0.0.0 without BIOPLAN_API_TOKEN. Port 8000 is the API and the
# dashboard, 8080 the 3-D viewer (BIOPLAN_VIEWER_PORT). Dependencies are installed at the versions
# of requirements/lock.txt, and the image has the video environment (MediaPipe 0.10.21 with the
# pins of requirements/pose.txt) in /opt/pose-env.
#
# The application is installed from the wheel built in the first stage, exactly as `pip install`
# would install it anywhere: the dashboard's pages and the database migrations are inside the
# package. tests/api/test_deployment.py builds a wheel from what the first stage copies and
# checks that it holds the same files as the wheel built from the repository.

# ---- the wheel ----------------------------------------------------------------------------
FROM python:3.11-slim-bookworm AS wheel
ENV PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1
WORKDIR /src
COPY pyproject.toml README.md LICENSE ./
COPY app ./app
RUN pip wheel --no-deps --wheel-dir /wheels .

# ---- the image ----------------------------------------------------------------------------
FROM python:3.11-slim-bookworm

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1

# libgomp: OpenMP runtime used by the numerical wheels; the health check uses Python, not curl.
RUN apt-get update \
    && apt-get install -y --no-install-recommends libgomp1 \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --create-home --uid 1000 bioplan \
    && mkdir -p /data \
    && chown bioplan /data

# Dependencies first, from pyproject.toml and the lock file alone (cached while only the code
# changes), each at the version requirements/lock.txt pins.
COPY pyproject.toml /tmp/pyproject.toml
COPY requirements/lock.txt requirements/pose.txt /tmp/requirements/
RUN python -c "import tomllib; print('\n'.join(tomllib.load(open('/tmp/pyproject.toml', 'rb'))['project']['dependencies']))" > /tmp/requirements.txt \
    && pip install -c /tmp/requirements/lock.txt -r /tmp/requirements.txt "psycopg[binary]>=3.2" \
    && rm /tmp/pyproject.toml /tmp/requirements.txt

# The application: the wheel, nothing else from the build context.
COPY --from=wheel /wheels /wheels
RUN pip install --no-deps /wheels/*.whl \
    && rm -rf /wheels \
    && python -c "import app.main, app.jobs.tasks, distributed"

# The video environment: MediaPipe 0.10.21 needs numpy<2, so it gets its own (venv + pip here,
# pinned by requirements/pose.txt); `bioplan pose-env` checks that it imports.
RUN PIP_CONSTRAINT=/tmp/requirements/pose.txt bioplan pose-env /opt/pose-env --verbose \
    && rm -rf /tmp/requirements
ENV BIOPLAN_POSE_PYTHON=/opt/pose-env/bin/python

USER bioplan
WORKDIR /data
ENV BIOPLAN_DATA_DIR=/data \
    BIOPLAN_PORT=8000
VOLUME ["/data"]
EXPOSE 8000 8080

HEALTHCHECK --interval=30s --timeout=5s --start-period=30s --retries=3 \
    CMD python -c "import urllib.request, os; urllib.request.urlopen('http://127.0.0.1:' + os.environ.get('BIOPLAN_PORT', '8000') + '/api/health', timeout=4)"

# `bioplan serve` runs `alembic upgrade head` (migrations from the package), then uvicorn with
# one worker process.
CMD ["bioplan", "serve"]
