"""How the tuning procedure reaches a drive: typed object access, the drive's clock, the
drive-side recorder and the test signal generator (docs/tuning.md).

The procedure (services/tuning/own) is written against :class:`TuningIO` only, so the same
code tunes a drive through a session (wall clock, SDO over the bus) and a simulated drive in the
benchmark (simulated time, stepped as fast as the computer allows; servodesk/benchmarks/tuning.py).
"""

from __future__ import annotations

import asyncio
import time
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, Value
from servodesk.domain.profile import DeviceProfile, RecorderSpec
from servodesk.errors import DriveStateError, NotFoundError
from servodesk.services.session import Session

FloatArray = NDArray[np.float64]

#: Recorder status values (docs/scope.md, "Simulated drive-side recorder": control/status).
REC_IDLE, REC_WAITING, REC_RECORDING, REC_DONE = 0, 1, 2, 3


class TuningIO(Protocol):
    """Typed object access and time, as the tuning procedure needs them."""

    profile: DeviceProfile

    async def read(self, address: ObjectAddress) -> Value: ...

    async def write(self, address: ObjectAddress, value: Value) -> None: ...

    async def read_bytes(self, address: ObjectAddress) -> bytes: ...

    async def sleep(self, seconds: float) -> None: ...

    def now(self) -> float: ...


class SessionIO:
    """A session's drive on the wall clock; writes are audited in the client's name."""

    def __init__(self, session: Session, client: str | None = None) -> None:
        self.session = session
        self.profile = session.profile
        self.client = client

    async def read(self, address: ObjectAddress) -> Value:
        value = (await self.session.read_object(address)).value
        if value is None:
            raise DriveStateError(f"{address} gives no value the profile can decode")
        return value

    async def write(self, address: ObjectAddress, value: Value) -> None:
        await self.session.write_object(address, value, client=self.client)

    async def read_bytes(self, address: ObjectAddress) -> bytes:
        return await self.session.link.read(address)

    async def sleep(self, seconds: float) -> None:
        await asyncio.sleep(seconds)

    def now(self) -> float:
        return time.monotonic()


async def read_float(io: TuningIO, address: ObjectAddress) -> float:
    """An object's value as a float (numbers only)."""
    v = await io.read(address)
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise DriveStateError(f"{address} is not a number ({v!r})")
    return float(v)


class Recording:
    """What one recording holds: each channel's samples (engineering value of the raw word)
    at ``rate_hz``, sample 0 at the start."""

    def __init__(self, rate_hz: float, channels: dict[ObjectAddress, FloatArray]) -> None:
        self.rate_hz = rate_hz
        self.channels = channels

    def __getitem__(self, address: ObjectAddress) -> FloatArray:
        return self.channels[address]

    @property
    def samples(self) -> int:
        return len(next(iter(self.channels.values()))) if self.channels else 0

    @property
    def t(self) -> FloatArray:
        return np.arange(self.samples, dtype=np.float64) / self.rate_hz


class DriveRecorder:
    """The drive-side recorder (docs/scope.md), free running from the start command.

    ``rate_hz`` is the recorder's rate at divider 1: the servo loop rate of the drive.
    """

    def __init__(self, io: TuningIO, rate_hz: float) -> None:
        spec = io.profile.recorder
        if spec is None:
            raise NotFoundError(
                f"{io.profile.name} has no drive-side recorder",
                hint="servodesk's own tuning needs the recorder to measure the response",
            )
        self.io = io
        self.spec: RecorderSpec = spec
        self.rate_hz = rate_hz
        self._channels: list[ObjectAddress] = []
        self._types: list[DataType] = []
        self._divider = 1

    def _addr(self, offset: int, sub: int = 0) -> ObjectAddress:
        return ObjectAddress(self.spec.object_index(offset), sub)

    async def _write(self, address: ObjectAddress, value: int) -> None:
        await self.io.write(address, value)

    async def configure(
        self, channels: list[ObjectAddress], seconds: float, divider: int = 1
    ) -> int:
        """Channels (at most the recorder's), the divider and a depth covering ``seconds``;
        returns the depth in samples."""
        spec = self.spec
        if len(channels) > spec.max_channels:
            raise DriveStateError(f"the recorder has {spec.max_channels} channels")
        types: list[DataType] = []
        for a in channels:
            s = self.io.profile.spec(a)
            if s is None:
                raise NotFoundError(f"{a} is not in the profile of {self.io.profile.name}")
            types.append(s.data_type)
        depth = max(2, min(spec.max_depth, round(seconds * self.rate_hz / divider)))
        await self._write(self._addr(RecorderSpec.CONTROL), 0)
        for n in range(1, spec.max_channels + 1):
            entry = 0
            if n <= len(channels):
                a = channels[n - 1]
                entry = a.index << 16 | a.subindex << 8 | types[n - 1].bits
            await self._write(self._addr(RecorderSpec.CHANNELS, n), entry)
        await self._write(self._addr(RecorderSpec.DIVIDER), divider)
        await self._write(self._addr(RecorderSpec.TRIGGER), 0)
        await self._write(self._addr(RecorderSpec.DEPTH), depth)
        self._channels = list(channels)
        self._types = types
        self._divider = divider
        return depth

    async def start(self) -> None:
        await self._write(self._addr(RecorderSpec.CONTROL), 1)

    async def stop(self) -> None:
        await self._write(self._addr(RecorderSpec.CONTROL), 0)

    async def finish(self, timeout_s: float = 10.0) -> Recording:
        """Wait until the recording is complete and upload it."""
        control = self._addr(RecorderSpec.CONTROL)
        start = self.io.now()
        while True:
            status = int(await read_float(self.io, control))
            if status == REC_DONE:
                break
            if status == REC_IDLE:
                raise DriveStateError("the drive's recorder stopped before it was done")
            if self.io.now() - start > timeout_s:
                raise DriveStateError("the drive's recorder did not finish in time")
            await self.io.sleep(0.01)
        count = int(await read_float(self.io, self._addr(RecorderSpec.COUNT)))
        data = await self.io.read_bytes(self._addr(RecorderSpec.DATA))
        n = len(self._channels)
        words = np.frombuffer(data, dtype="<u4")
        if n == 0 or len(words) != count * n:
            raise DriveStateError(
                f"the recorder's data has {len(words)} words for {count} samples x {n} channels"
            )
        words = words.reshape(count, n)
        out: dict[ObjectAddress, FloatArray] = {}
        for i, (a, dt) in enumerate(zip(self._channels, self._types, strict=True)):
            col = words[:, i]
            if dt is DataType.REAL32:
                out[a] = col.view("<f4").astype(np.float64)
            elif dt.is_signed:
                out[a] = col.view("<i4").astype(np.float64)
            else:
                out[a] = col.astype(np.float64)
        return Recording(self.rate_hz / self._divider, out)
