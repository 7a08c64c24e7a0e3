"""HTTP and WebSocket API (FastAPI): thin routes over the services."""
