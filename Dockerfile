# servodesk: build the UI, build the wheel, run the backend with simulated drives.
#   docker build -t servodesk . && docker run --rm -p 8000:8000 servodesk
# Inside the container the server binds 0.0.0.0, so it requires a token: set SERVODESK_TOKEN or
# read the generated one (with the URL to open) from the container's log.

FROM node:20-bookworm-slim AS ui
WORKDIR /src/frontend
COPY frontend/package.json frontend/package-lock.json ./
RUN npm install --no-save --no-audit --no-fund --loglevel=error
COPY frontend/ ./
# vite.config.ts writes the build into ../backend/servodesk/web/dist.
RUN mkdir -p ../backend/servodesk/web && npm run build

FROM python:3.11-slim-bookworm AS wheel
WORKDIR /src
RUN pip install --no-cache-dir uv==0.13.9
COPY pyproject.toml uv.lock README.md ./
COPY backend/ backend/
COPY profiles/ profiles/
COPY --from=ui /src/backend/servodesk/web/dist backend/servodesk/web/dist
RUN uv export --frozen --no-dev --no-emit-project -o requirements.txt && uv build --wheel -o /dist

FROM python:3.11-slim-bookworm
RUN useradd --create-home servodesk
COPY --from=wheel /src/requirements.txt /tmp/requirements.txt
COPY --from=wheel /dist/*.whl /tmp/
RUN pip install --no-cache-dir -r /tmp/requirements.txt && pip install --no-cache-dir --no-deps /tmp/*.whl && rm /tmp/*.whl /tmp/requirements.txt
USER servodesk
ENV SERVODESK_HOST=0.0.0.0 SERVODESK_PORT=8000
EXPOSE 8000
CMD ["servodesk", "serve", "--sim"]
