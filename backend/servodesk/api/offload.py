"""Heavy work off the event loop: parsing and serialising large documents in a worker thread.

The event loop carries every session's traffic and the dead-man's heartbeats. Until
2026-12-07 a GET of a 35 MB backup, a compare or preflight with it, or the import of a 10 MB
scope CSV held it for 2.5 to 9 s (issue "Motion safety", item 3): the heartbeats of a live
client waited unread, and the dead-man (services/deadman.py) now stops the axis in that case
rather than wait. So the documents are parsed, validated and turned into JSON bytes in a
worker thread, and the route returns the finished bytes: FastAPI would otherwise validate and
``json.dumps`` the returned model on the loop (its JSONResponse renders in ``__init__``).
Such routes declare ``response_model`` for the schema and return :func:`json_response`.

A thread is not enough where one C call holds the GIL for long: the scope's CSV parser held
it for up to 1.9 s at a time on a 10 MB file (NumPy's text conversion), and the loop waited as
if the work were on it. That work runs in a spawned process (:func:`in_process`), as the
tuning's searches do (services/tuning/worker.py); its function and arguments must pickle.
"""

from __future__ import annotations

import asyncio
import json
import multiprocessing
import os
import tempfile
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, ParamSpec, TypeVar

from fastapi import Response
from fastapi.responses import FileResponse
from pydantic import BaseModel
from starlette.background import BackgroundTask

from servodesk.errors import WorkerFailed

P = ParamSpec("P")
T = TypeVar("T")

_POOL: ProcessPoolExecutor | None = None


def _pool() -> ProcessPoolExecutor:
    """One spawned worker (not forked: the server's bus threads would be copied in whatever
    state they are), started on first use; it dies with the server (the hook of
    services/tuning/worker.py)."""
    global _POOL
    if _POOL is None:
        from servodesk.services.tuning.worker import _die_with_parent

        _POOL = ProcessPoolExecutor(
            1, mp_context=multiprocessing.get_context("spawn"), initializer=_die_with_parent
        )
    return _POOL


async def in_process(fn: Callable[P, T], *args: P.args, **kwargs: P.kwargs) -> T:
    """Run ``fn`` in the documents' worker process; its exceptions come back pickled (the
    error tree pickles: errors.py). A worker that died (killed for memory by a huge file)
    is a 503 for this request, and the next one starts a new worker: a broken pool would
    otherwise refuse every later document."""
    global _POOL
    pool = _pool()
    try:
        return await asyncio.wrap_future(pool.submit(fn, *args, **kwargs))
    except BrokenProcessPool:
        if _POOL is pool:
            _POOL = None
            pool.shutdown(wait=False, cancel_futures=True)
        raise WorkerFailed(
            "the worker process that reads large documents ended before it answered",
            hint="try again; if it fails again, the file may be too large for this machine's "
            "memory",
        ) from None


async def file_answer(
    fn: Callable[..., None], *args: Any, media_type: str = "application/json"
) -> Response:
    """Run ``fn(*args, out)`` in the documents' worker, which writes the answer to the
    temporary file ``out``; stream that file and remove it. A large answer crosses into the
    server a chunk at a time (api/backup_documents.py says why)."""
    fd, out = tempfile.mkstemp(prefix="servodesk-answer-", suffix=".json")
    os.close(fd)
    try:
        await in_process(fn, *args, out)
    except BaseException:
        os.unlink(out)
        raise
    return FileResponse(out, media_type=media_type, background=BackgroundTask(os.unlink, out))


def shutdown() -> None:
    global _POOL
    if _POOL is not None:
        _POOL.shutdown(wait=False, cancel_futures=True)
        _POOL = None


async def in_worker(fn: Callable[P, T], *args: P.args, **kwargs: P.kwargs) -> T:
    """Run ``fn`` in a worker thread; its exceptions (the error tree) come back as they are."""
    return await asyncio.to_thread(fn, *args, **kwargs)


def json_bytes(value: Any, model: type[BaseModel] | None = None) -> bytes:
    """The JSON the route would have answered: through ``model`` when given (the response
    model's validation), compact, no NaN (Starlette's JSONResponse does the same)."""
    if model is not None:
        return model.model_validate(value).model_dump_json().encode("utf-8")
    return json.dumps(
        value, ensure_ascii=False, allow_nan=False, separators=(",", ":"), default=str
    ).encode("utf-8")


async def json_response(
    make: Callable[[], Any], model: type[BaseModel] | None = None, status_code: int = 200
) -> Response:
    """Build the answer (``make()``) and its JSON bytes in a worker thread."""

    def build() -> bytes:
        return json_bytes(make(), model)

    body = await asyncio.to_thread(build)
    return Response(body, status_code=status_code, media_type="application/json")
