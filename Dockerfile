# The backlash service: `docker build -t backlash .` then
#   docker run -p 8000:8000 -v backlash-data:/data -e BACKLASH_API_KEY=<a key of 8+ characters> backlash
# It listens on 0.0.0.0 inside the container, so it starts only with an API key (clients send it in the
# X-API-Key header), or with -e BACKLASH_ALLOW_NO_KEY=1 where every client that can reach the port is trusted.
# Settings are BACKLASH_* environment variables (see app/core/config.py); the database (pattern
# sets, jobs, records, diagnoses) lives on the /data volume. Other commands: docker run backlash backlash --help
# Without access to a container registry, build a local stand-in for the base from Debian's packages
# (docs/container.md): docker build --network host --build-arg BASE_IMAGE=local/python:3.11-slim -t backlash .
# Any base works that has Debian's apt-get and a Python 3.11 whose `python` and `pip` are on PATH.
ARG BASE_IMAGE=python:3.11-slim
FROM ${BASE_IMAGE}

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    NUMBA_CACHE_DIR=/home/app/.cache/numba \
    NUMBA_THREADING_LAYER=omp \
    BACKLASH_DB_PATH=/data/patterns.sqlite3

# libgomp: numba's OpenMP threading layer, safe when several threads simulate at once
RUN apt-get update \
    && apt-get install -y --no-install-recommends libgomp1 \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --create-home --uid 10001 --shell /usr/sbin/nologin app \
    && mkdir -p /data "$NUMBA_CACHE_DIR" \
    && chown -R app:app /data /home/app/.cache

WORKDIR /app

# 1. the dependencies alone, at the versions CI tested (constraints.txt):
#    this layer is rebuilt only when pyproject.toml or constraints.txt changes
COPY pyproject.toml constraints.txt ./
RUN python -c "import tomllib; print('\n'.join(tomllib.load(open('pyproject.toml', 'rb'))['project']['dependencies']))" \
        > /tmp/requirements.txt \
    && pip install -c constraints.txt -r /tmp/requirements.txt \
    && rm /tmp/requirements.txt

# 2. the code
COPY README.md ./
COPY engine ./engine
COPY app ./app
COPY bench ./bench
# (the sources are removed after installing, so every import, the numba cache's included, uses site-packages)
RUN pip install --no-deps . \
    && rm -rf build ./*.egg-info engine app \
    && chown app:app /app

USER app

# build matplotlib's font cache (in /home/app/.cache) now, not in every new container and worker process
RUN python -c "import matplotlib.pyplot"
# compile the numba kernels into NUMBA_CACHE_DIR now, so the first request is fast: the drive's serial and
# parallel kernels, the EMPS loop and the BRFD element on their records shipped in the package (which also proves
# the records are there), the speed quantum's scan and the paper's network (engine/warm_up.py, as `make test`)
RUN python -m engine.warm_up

VOLUME ["/data"]
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=5s --start-period=60s --retries=3 \
    CMD ["python", "-c", "import sys, urllib.request; sys.exit(0 if urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=4).status == 200 else 1)"]
CMD ["backlash", "serve", "--host", "0.0.0.0", "--port", "8000"]
