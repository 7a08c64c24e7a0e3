"""Restoring a backup into a drive: preflight, ordered and verified writes, resume.

A restore never writes before its preflight passed (identity, profile, state, every value's
type and range, writability now). It first reads the drive's present parameters (the
automatic backup, saved once the preflight passed; the preflight's values are taken from it
rather than read again), records the restore and all its items in the store, then writes in
the order :func:`~servodesk.domain.restore_plan.plan_writes` gives and reads every value back.

**Group commit with a write-ahead intent.** The writes go in batches (:data:`BATCH_STEPS`,
:data:`BATCH_SECONDS`). Before a batch, one transaction of the journal marks its items as
being written (:data:`INTENT`) and the audit chain gets a ``restore.batch`` record listing
each object with its old value (from the automatic backup) and its new one; after it, the
batch's results (item statuses, and one ``write.object`` audit record per write) are committed
together with the next batch's intent. A commit is an fsync (~1 ms): one per entry cost more
than the write and its read-back together (issue 50), so they run per batch, in a thread (the
event loop, and so a stop or the dead-man, never waits on the database). A lost bus or a reset
drive stops the restore with a report that names exactly which items were written and
verified; a crash mid-batch leaves that batch's items pending under their intent. Either way
:meth:`RestoreService.resume` re-reads every item from the drive (the drive is the truth for
a pending batch), records in the audit log the intended writes it finds done, and writes
what is still missing. Parameters are stored to non-volatile memory only when every item
verified (or when forced).

Over 700 lines: the restore, its batches' write-ahead journal (:class:`_Journal`) and resume
read and write the same journal rows and audit chain; the pure preflight and write plan are
domain/restore_plan.py.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Awaitable, Mapping
from dataclasses import replace
from typing import Any

from servodesk.domain import cia402, paramset, restore_plan
from servodesk.domain.address import ObjectAddress
from servodesk.domain.paramset import ParameterSet
from servodesk.domain.restore_plan import DriveFacts, Preflight, RestoreProblem, RestoreStep
from servodesk.errors import (
    ConflictError,
    DriveStateError,
    LinkError,
    ObjectAccessError,
    ServodeskError,
    ValidationError,
)
from servodesk.services.backup import (
    WRITE_FACTS,
    BackupService,
    bus_of,
    drive_key,
    firmware,
    new_id,
    now_iso,
)
from servodesk.services.backup import progress as publish_progress
from servodesk.services.backup_files import restore_targets
from servodesk.services.session import Session

log = logging.getLogger(__name__)

#: Writes per batch: one intent (journal and audit chain) each. A verified write costs ~0.34 ms
#: on a fast bus and a commit ~1.1 ms (WAL, synchronous=FULL): at 64, a batch's ~22 ms of bus
#: time hides its commits (the next batch's intent commits while this one is written);
#: larger batches gain nothing more and widen what a crash leaves for resume to read.
BATCH_STEPS = 64
#: Within a batch, its results so far are committed at least this often: on a slow link
#: (125 kbit/s CAN, PROFINET, SLMP) 64 writes take seconds, and the journal (the report, and
#: what a resume after a crash trusts without reading) stays within 0.1 s of the drive.
BATCH_SECONDS = 0.1
#: The journal's message of an item whose batch's intent is committed and whose result is
#: not yet: if the restore stops there (a crash), resume reads it from the drive.
INTENT = (
    "in batch {batch}, being written (if the restore stopped here: resume reads it from the drive)"
)
_INTENT_HEAD = INTENT.split("{", 1)[0]
#: The message of the item whose write the lost bus cut (services/restore.py ``_run``).
_INTERRUPTED_HEAD = "interrupted at "


def _maybe_written(row: dict[str, Any]) -> bool:
    """A pending item whose own write may have reached the drive: its batch was being
    written, or the lost bus cut its write (not an object of the same PDO procedure that
    was only marked pending beside it: its write is in the audit log already)."""
    text = row["message"] or ""
    return text.startswith(_INTENT_HEAD) or text.startswith(f"{_INTERRUPTED_HEAD}{row['address']} ")


def _problems_text(problems: list[RestoreProblem]) -> str:
    lines = []
    for p in problems:
        lines.append(f"{p.message}" + (f" ({p.hint})" if p.hint else ""))
    return "; ".join(lines)


class PreflightFailed(ValidationError):
    """The preflight found problems; nothing was written. ``problems`` lists every one."""

    def __init__(self, problems: list[RestoreProblem]) -> None:
        super().__init__(
            f"restore refused, nothing was written: {len(problems)} problem(s): "
            + _problems_text(problems),
            field="backup",
            hint="correct every listed problem, then run the restore again",
        )
        self.problems = problems

    def to_dict(self) -> dict[str, object]:
        out = super().to_dict()
        out["problems"] = [p.to_dict() for p in self.problems]
        return out


class PreflightStateConflict(DriveStateError):
    """Like :class:`PreflightFailed`, when the drive's state is among the problems (409)."""

    def __init__(self, problems: list[RestoreProblem]) -> None:
        super().__init__(
            f"restore refused, nothing was written: {len(problems)} problem(s): "
            + _problems_text(problems),
            hint="correct every listed problem, then run the restore again",
        )
        self.problems = problems

    def to_dict(self) -> dict[str, object]:
        out = super().to_dict()
        out["problems"] = [p.to_dict() for p in self.problems]
        return out


def refusal(pf: Preflight) -> ServodeskError:
    """The error of a preflight that did not pass (409 when the drive's state is the problem)."""
    if any(p.address is None and "not enabled" in p.message for p in pf.problems):
        return PreflightStateConflict(pf.problems)
    return PreflightFailed(pf.problems)


def _state_id(session_state: str) -> str:
    return session_state.lower().replace(" ", "_")


class RestoreService:
    def __init__(self, backups: BackupService) -> None:
        self.backups = backups
        self.store = backups.store
        self._locks: dict[str, asyncio.Lock] = {}

    # Facts and preflight -------------------------------------------------------------------

    async def facts(
        self,
        session: Session,
        addresses: list[ObjectAddress],
        known: Mapping[ObjectAddress, bytes | None] | None = None,
    ) -> DriveFacts:
        """What the preflight needs of the drive. ``known``: values read moments ago (the
        automatic backup; None: the drive refused it), not read again."""
        state: str | None
        try:
            st = await session.drive_state()
            state = None if st.state == cia402.State.UNKNOWN.value else _state_id(st.state)
            nmt = st.nmt_state
        except LinkError:
            raise
        except ServodeskError:
            state, nmt = None, await session.link.network_state()
        known = known or {}
        current: dict[ObjectAddress, bytes | None] = {a: known[a] for a in addresses if a in known}
        unknown = [a for a in addresses if a not in known]
        results = await session.link.read_many(unknown)
        for a, r in zip(unknown, results, strict=True):
            current[a] = None if isinstance(r, ServodeskError) else r
        return DriveFacts(
            profile=session.profile,
            identity={
                "vendor_id": session.identity.vendor_id,
                "product_code": session.identity.product_code,
                "revision": session.identity.revision,
                "serial": session.identity.serial,
            },
            firmware=firmware(session),
            state=state,
            nmt=nmt,
            current=current,
            counts_per_rev=session.counts_per_rev,
            profile_counts_per_rev=session.profile_counts_per_rev,
        )

    def _targets(self, session: Session, ps: ParameterSet, map_names: bool) -> list[ObjectAddress]:
        return restore_targets(ps, session.profile, map_names)

    async def preflight(
        self,
        session: Session,
        ps: ParameterSet,
        *,
        map_names: bool = False,
        known: Mapping[ObjectAddress, bytes | None] | None = None,
    ) -> tuple[Preflight, DriveFacts]:
        facts = await self.facts(session, self._targets(session, ps, map_names), known)
        return restore_plan.preflight(ps, facts, map_names=map_names), facts

    # Restore --------------------------------------------------------------------------------

    def _lock(self, session: Session) -> asyncio.Lock:
        lock = self._locks.get(session.id)
        if lock is None:
            lock = self._locks[session.id] = asyncio.Lock()
        if lock.locked():
            raise ConflictError(
                f"a restore into {session.id} is already running",
                hint="wait for it to finish (its progress is on the WebSocket)",
            )
        return lock

    async def restore(
        self,
        session: Session,
        backup_id: str,
        *,
        dry_run: bool = False,
        store: bool = True,
        force: bool = False,
        map_by_name: bool = False,
        client: str = "unknown",
        rewrite_all: bool = False,
    ) -> dict[str, Any]:
        """Restore backup ``backup_id`` into ``session`` (see the module docstring).

        ``rewrite_all`` writes (and verifies) unchanged entries too, e.g. to measure the
        write path or to be sure every value went through the drive's own checks.
        """
        # Off the loop (docs/safety.md): parsing a large backup held it for seconds. It is
        # parsed while the drive is read (issue 50: the disk and the bus at once).
        loading = asyncio.ensure_future(asyncio.to_thread(self.backups.load, backup_id))
        try:
            return await self._restore(
                session, backup_id, loading, dry_run, store, force, map_by_name, client,
                rewrite_all,
            )  # fmt: skip
        finally:
            if not loading.done():
                loading.cancel()
            elif not loading.cancelled():
                loading.exception()  # Seen: a backup that did not load is the answer's error.

    async def _restore(
        self,
        session: Session,
        backup_id: str,
        loading: asyncio.Future[ParameterSet],
        dry_run: bool,
        store: bool,
        force: bool,
        map_by_name: bool,
        client: str,
        rewrite_all: bool,
    ) -> dict[str, Any]:
        if dry_run:
            ps = await loading
        async with self._lock(session):
            before: ParameterSet | None = None
            known: dict[ObjectAddress, bytes | None] = {}
            if not dry_run:
                # The drive's present parameters, as a backup of its own (saved below, once
                # the preflight passed). The preflight takes its values from them: reading
                # them twice cost a full pass over the bus (issue 50).
                before = await self.backups.read_set(
                    session,
                    label=f"before restore of {backup_id}",
                    note="taken automatically before a restore",
                )
                known = {e.address: e.raw for e in before.entries}
                known |= {u.address: None for u in before.unreadable}
                ps = await loading
            pf, facts = await self.preflight(session, ps, map_names=map_by_name, known=known)
            if not pf.ok:
                raise refusal(pf)
            if rewrite_all:
                pf = replace(
                    pf,
                    items=[
                        replace(it, status="would_write") if it.status == "unchanged" else it
                        for it in pf.items
                    ],
                )
            steps, items = self._plan(session, pf, facts)
            rid = new_id("r")
            options = {
                "store": store,
                "force": force,
                "map_by_name": map_by_name,
                "client": client,
                "warnings": pf.warnings,
                "steps": [_step_dict(s) for s in steps],
                # What the backup lacks: the report says what this restore could not set.
                "unreadable": paramset.unreadable_dicts(ps.unreadable),
            }
            meta = {
                "id": rid,
                "backup": backup_id,
                "session": session.id,
                "drive_key": drive_key(session),
                "bus": bus_of(session),
                "time": now_iso(),
                "dry_run": dry_run,
                "finished": dry_run,
                "options": options,
            }
            if before is None:
                await asyncio.to_thread(
                    self.store.add_restore, meta, [_item_dict(it) for it in items]
                )
                return self.report(rid)
            rows = [_item_dict(it, pending=True) for it in items]

            def record(before: ParameterSet = before) -> None:
                # The drive's values saved, then the restore's rows: one trip off the loop.
                meta["pre_backup"] = self.backups.save(before, "pre-restore")["id"]
                self.store.add_restore(meta, rows)

            await asyncio.to_thread(record)
            # The audit's old value of each object: the automatic backup's (issue 50: not a
            # read of its own per write); facts.current for what the backup does not hold.
            old = {**facts.current, **{e.address: e.raw for e in before.entries}}
            await self._run(rid, session, steps, rows, client, old)
            return await self._finish(rid, session, options)

    def _plan(
        self, session: Session, pf: Preflight, facts: DriveFacts
    ) -> tuple[list[RestoreStep], list[restore_plan.PlanItem]]:
        to_write = {it.address: it.new_raw for it in pf.items if it.status == "would_write"}
        targets = {
            it.address: it.new_raw for it in pf.items if it.status in ("would_write", "unchanged")
        }
        steps = restore_plan.plan_writes(
            session.profile,
            {a: r for a, r in to_write.items() if r is not None},
            {a: r for a, r in targets.items() if r is not None},
            facts.current,
        )
        # Items in the order they are written; the others after them by address.
        pos = {s.entry: i for i, s in enumerate(steps) if s.entry is not None}
        items = sorted(pf.items, key=lambda it: (pos.get(it.address, len(steps)), it.address))
        return steps, items

    async def _run(
        self,
        rid: str,
        session: Session,
        steps: list[RestoreStep],
        rows: list[dict[str, Any]],
        client: str,
        old: Mapping[ObjectAddress, bytes | None],
    ) -> None:
        """Write ``steps`` in batches (module docstring); ``old``: each object's value
        before the restore (the audit's old value)."""
        seq = {ObjectAddress.parse(r["address"]): i for i, r in enumerate(rows)}
        status = {i: r["status"] for i, r in enumerate(rows)}
        resets = session.link.resets_seen
        failed_groups: dict[str, str] = {}
        touched: dict[str, set[ObjectAddress]] = {}
        total = len(steps) or 1
        journal = _Journal(self, rid, session, client, rows, old)

        def set_item(a: ObjectAddress, **fields: Any) -> None:
            i = seq.get(a)
            if i is None:
                return
            if "status" in fields:
                status[i] = fields["status"]
            journal.item(i, fields)

        def fail_group(group: str, reason: str) -> None:
            failed_groups[group] = reason
            # Objects the procedure changed on the way (PDO invalid, count 0) are not as
            # the report would otherwise claim: say so.
            for a in touched.get(group, set()):
                i = seq.get(a)
                if i is not None and status[i] == "unchanged":
                    set_item(a, status="failed", message=f"left changed: {reason}")

        batches = [steps[i : i + BATCH_STEPS] for i in range(0, len(steps), BATCH_STEPS)]

        def intent(k: int) -> Awaitable[None]:
            b = batches[k]
            return journal.commit(intent=b, seqs=[seq[s.entry] for s in b if s.entry in seq])

        # One commit at a time, in order; the intent of batch k+1 (with the results so far)
        # commits while batch k is written, so the bus does not wait for the disk; a batch's
        # first write waits only until its own intent is committed.
        inflight: asyncio.Future[None] | None = None
        if batches:
            await intent(0)
        n = 0
        for k, batch in enumerate(batches):
            if k + 1 < len(batches):
                inflight = asyncio.ensure_future(intent(k + 1))
            committed = time.monotonic()
            for step in batch:
                n += 1
                if time.monotonic() - committed >= BATCH_SECONDS and (
                    inflight is None or inflight.done()
                ):
                    # A slow link: the results so far, without waiting for the batch's end.
                    if inflight is not None:
                        inflight.result()  # A failed commit stops the restore here.
                    inflight = asyncio.ensure_future(journal.commit())
                    committed = time.monotonic()
                if step.group in failed_groups and step.group != str(step.address):
                    if step.entry is not None:
                        set_item(
                            step.entry,
                            status="failed",
                            message=f"not written: {failed_groups[step.group]}",
                        )
                    continue
                name = rows[seq[step.entry]]["name"] if step.entry in seq else step.why
                publish_progress(
                    session,
                    "restore",
                    (n - 1) / total,
                    f"writing {step.address} {name}",
                    item={"address": str(step.address), "name": name, "why": step.why},
                )
                touched.setdefault(step.group, set()).add(step.address)
                try:
                    got = await session.write_object(
                        step.address, raw_hex=step.raw.hex(), client=client, audited=False
                    )
                except LinkError as exc:
                    # The write may or may not have landed: pending, checked again on resume.
                    # So are the objects a PDO procedure had changed on the way.
                    why = f"{_INTERRUPTED_HEAD}{step.address} ({step.why}): {exc.message}"
                    if step.entry is not None:
                        set_item(step.entry, status="pending", message=why)
                    for a in touched.get(step.group, set()) - {step.entry}:
                        i = seq.get(a)
                        if i is not None and status[i] in ("unchanged", "written"):
                            set_item(a, status="pending", message=why)
                    if inflight is not None:
                        await inflight
                    journal.release()
                    await journal.commit(
                        restore={
                            "interrupted": True,
                            "message": f"interrupted at {step.address} {name}: {exc.message}; "
                            "resume when the drive answers again",
                        }
                    )
                    publish_progress(
                        session, "restore", (n - 1) / total, f"interrupted: {exc.message}"
                    )
                    return
                except ObjectAccessError as exc:
                    reason = f"{step.address} ({step.why}) refused: 0x{exc.code:08X} {exc.meaning}"
                    if step.entry is not None:
                        set_item(
                            step.entry,
                            status="failed",
                            code=exc.code,
                            meaning=exc.meaning,
                            message=exc.message,
                        )
                    fail_group(step.group, reason)
                    continue
                except ServodeskError as exc:
                    if step.entry is not None:
                        set_item(step.entry, status="failed", message=exc.message)
                    fail_group(step.group, f"{step.address} ({step.why}): {exc.message}")
                    continue
                back = bytes.fromhex(got.raw_hex)
                journal.wrote(step.address, step.raw, back)
                if back != step.raw:
                    reason = f"{step.address} read back {back.hex()} after writing {step.raw.hex()}"
                    if step.entry is not None:
                        set_item(step.entry, status="failed", message=reason)
                    fail_group(step.group, reason)
                    continue
                if step.entry is not None:
                    set_item(step.entry, status="written", message=None)
            if inflight is not None:
                await inflight  # The next batch's intent is committed.
                inflight = None
        journal.release()
        await journal.commit()
        # Final check: every written value is still there. A drive that reset (or was
        # changed by someone else) meanwhile has lost them: pending again, resumable. A
        # value that differs from the drive's before the restore shows that; one equal to it
        # reads the same after a reset unless the drive's EEPROM held another value than
        # its RAM, so those are read again only when the link saw the drive reset (CANopen:
        # a boot-up message) during the writes (issue 50: a restore at the bus's pace).
        reset = session.link.resets_seen != resets
        done = []
        for i, st in status.items():
            if st != "written":
                continue
            a = ObjectAddress.parse(rows[i]["address"])
            if reset or old.get(a) != bytes.fromhex(rows[i]["new_raw_hex"]):
                done.append(i)
        addrs = [ObjectAddress.parse(rows[i]["address"]) for i in done]
        try:
            results = await session.link.read_many(addrs)  # The bytes are all it compares.
        except LinkError as exc:
            await journal.commit(
                restore={
                    "interrupted": True,
                    "message": f"final check interrupted: {exc.message}",
                }
            )
            return
        lost = 0
        for i, a, r in zip(done, addrs, results, strict=True):
            target = rows[i]["new_raw_hex"]
            if isinstance(r, ServodeskError) or r.hex() != target:
                lost += 1
                set_item(
                    a,
                    status="pending",
                    message="changed after it was written and verified (drive reset?)",
                )
        if lost:
            await journal.commit(
                restore={
                    "interrupted": True,
                    "message": f"{lost} written value(s) changed before the end of the "
                    "restore (drive reset?); resume to write them again",
                }
            )
            return
        publish_progress(session, "restore", 1.0, "all writes done")

    async def _finish(self, rid: str, session: Session, options: dict[str, Any]) -> dict[str, Any]:
        # Off the loop: a report of thousands of items takes a tenth of a second to build.
        rep = await asyncio.to_thread(self.report, rid)
        if rep["interrupted"] and rep["counts"]["pending"]:
            return rep
        c = rep["counts"]
        verified = c["failed"] == 0 and c["pending"] == 0
        stored = False
        message = None
        if options.get("store", True) and (verified or options.get("force")):
            try:
                await session.store()
                stored = True
            except LinkError as exc:
                await asyncio.to_thread(
                    self.store.set_restore,
                    rid,
                    interrupted=True,
                    message=f"storing failed: {exc.message}",
                )
                return await asyncio.to_thread(self.report, rid)
            except ServodeskError as exc:
                message = f"not stored: {exc.message}"
        elif options.get("store", True):
            message = (
                f"not stored to non-volatile memory: {c['failed']} item(s) failed; the drive "
                "keeps the values until it is reset (force to store anyway)"
            )
        await asyncio.to_thread(
            self.store.set_restore,
            rid,
            finished=True,
            interrupted=False,
            stored=stored,
            message=message,
        )
        # The report read above, with the fields just committed (its items did not change).
        return rep | {"finished": True, "interrupted": False, "stored": stored, "message": message}

    # Resume ---------------------------------------------------------------------------------

    async def resume(self, rid: str, session: Session, client: str = "unknown") -> dict[str, Any]:
        """Continue a restore: check every item against the drive, write what is missing."""
        rec = self.store.get_restore(rid)
        if rec["dry_run"]:
            raise ValidationError(
                f"restore {rid} was a dry run; nothing to resume",
                field="restore",
                hint="run the restore without dry_run",
            )
        if rec["finished"] and not any(
            it["status"] in ("pending", "failed") for it in rec["items"]
        ):
            return self.report(rid)
        options = rec["options"]
        ps = self.backups.load(rec["backup"])
        async with self._lock(session):
            self.store.set_restore(rid, session=session.id)
            rows = rec["items"]
            live = [r for r in rows if r["status"] in ("written", "pending", "failed", "unchanged")]
            live = [r for r in live if not (r["message"] or "").startswith("not mapped")]
            addresses = [ObjectAddress.parse(r["address"]) for r in live]
            facts = await self.facts(session, addresses)
            journal = _Journal(self, rid, session, client, rows, facts.current)
            # Still to do: every item whose value is not on the drive now (a reset drive
            # lost the ones written before it), whatever its status was. The drive is the
            # truth for a batch the restore stopped in: what it holds of its intent was
            # written, and goes into the audit log now (with the journal's old value, the
            # automatic backup's).
            missing: set[ObjectAddress] = set()
            for r, a in zip(live, addresses, strict=True):
                target = bytes.fromhex(r["new_raw_hex"])
                if facts.current.get(a) == target:
                    if r["status"] in ("pending", "failed"):
                        journal.item(
                            r["seq"], {"status": "written", "message": "verified on resume"}
                        )
                    if r["status"] == "pending" and _maybe_written(r):
                        prior = r["old_raw_hex"]
                        journal.found(a, bytes.fromhex(prior) if prior else None, target)
                else:
                    missing.add(ObjectAddress.parse(r["source"]))
            subset = replace(ps, entries=tuple(e for e in ps.entries if e.address in missing))
            pf = restore_plan.preflight(subset, facts, map_names=bool(options.get("map_by_name")))
            if not pf.ok:
                raise refusal(pf)
            targets = {
                a: bytes.fromhex(r["new_raw_hex"])
                for r, a in zip(live, addresses, strict=True)
                if r["status"] != "skipped_read_only"
            }
            to_write = {it.address: it.new_raw for it in pf.items if it.status == "would_write"}
            steps = restore_plan.plan_writes(
                session.profile,
                {a: r for a, r in to_write.items() if r is not None},
                targets,
                facts.current,
            )
            for it in pf.items:
                if it.status == "would_write":
                    journal.item(self._seq(rows, it.address), {"status": "pending"})
            await journal.commit(restore={"interrupted": False, "message": None})
            fresh = self.store.get_restore(rid)["items"]
            await self._run(rid, session, steps, fresh, client, facts.current)
            return await self._finish(rid, session, options)

    @staticmethod
    def _seq(rows: list[dict[str, Any]], address: ObjectAddress) -> int:
        text = str(address)
        for r in rows:
            if r["address"] == text:
                return int(r["seq"])
        raise ValidationError(f"{address} is not an item of this restore")

    # Reports --------------------------------------------------------------------------------

    def report(self, rid: str) -> dict[str, Any]:
        rec = self.store.get_restore(rid)
        counts = {
            "written": 0,
            "unchanged": 0,
            "skipped": 0,
            "failed": 0,
            "pending": 0,
            "would_write": 0,
        }
        items = []
        for it in rec["items"]:
            st = it["status"]
            key = "skipped" if st == "skipped_read_only" else st
            counts[key] = counts.get(key, 0) + 1
            code = it["code"]
            items.append(
                {
                    "address": it["address"],
                    "name": it["name"],
                    "status": st,
                    "old_raw_hex": it["old_raw_hex"],
                    "new_raw_hex": it["new_raw_hex"],
                    "code": code,
                    "code_hex": f"0x{code:08X}" if code is not None else None,
                    "meaning": it["meaning"],
                    "message": it["message"],
                }
            )
        options = rec["options"]
        return {
            "id": rec["id"],
            "backup": rec["backup"],
            "session": rec["session"],
            "time": rec["time"],
            "dry_run": rec["dry_run"],
            "finished": rec["finished"],
            "stored": rec["stored"],
            "interrupted": rec["interrupted"],
            "pre_backup": rec["pre_backup"],
            "message": rec["message"],
            "warnings": options.get("warnings", []),
            "counts": counts,
            "items": items,
            "steps": options.get("steps", []),
            "unreadable": options.get("unreadable", []),
        }


class _Journal:
    """A restore's journal and audit records between two group commits (module docstring).

    ``item`` and ``wrote`` only collect; ``commit`` writes what was collected (the results
    of the batch that ended) and the next batch's intent: one store transaction and one
    audit-chain transaction, in threads."""

    def __init__(
        self,
        service: RestoreService,
        rid: str,
        session: Session,
        client: str,
        rows: list[dict[str, Any]],
        old: Mapping[ObjectAddress, bytes | None],
    ) -> None:
        self.service = service
        self.rid = rid
        self.session = session
        self.client = client
        self.rows = rows
        #: Each object's value on the drive as the restore goes: the next write's old value.
        self.values: dict[ObjectAddress, bytes | None] = dict(old)
        #: ... and as the plan would leave it: the intents' old values (:meth:`_intended`).
        self._planned: dict[ObjectAddress, bytes | None] = dict(old)
        self.batch = 0
        self._items: dict[int, dict[str, Any]] = {}
        self._writes: list[tuple[dict[str, Any], dict[str, Any]]] = []  # (record, extra)
        #: Items under a committed intent whose result has not come yet.
        self._declared: set[int] = set()

    def item(self, i: int, fields: dict[str, Any]) -> None:
        self._items.setdefault(i, {}).update(fields)
        self._declared.discard(i)

    def release(self) -> None:
        """The restore stops: items under an intent that were not reached keep the message
        they had (the next commit writes it back)."""
        for i in self._declared:
            self._items.setdefault(i, {"message": self.rows[i]["message"]})
        self._declared.clear()

    def wrote(self, address: ObjectAddress, raw: bytes, back: bytes) -> None:
        """A write the drive took (``back``: what it read back)."""
        rec = self.service.backups.write_record(
            self.session, address, self.values.get(address), raw, self.client
        )
        self._writes.append((rec, {}))
        self.values[address] = back

    def found(self, address: ObjectAddress, old: bytes | None, new: bytes) -> None:
        """A write of a batch the restore stopped in, found done on the drive by resume."""
        rec = self.service.backups.write_record(self.session, address, old, new, self.client)
        self._writes.append((rec, {"found_on_resume": True}))

    async def commit(
        self,
        *,
        intent: list[RestoreStep] | None = None,
        seqs: list[int] | None = None,
        restore: dict[str, Any] | None = None,
    ) -> None:
        items, self._items = self._items, {}
        audit = self.service.backups.audit
        writes, self._writes = self._writes, []
        for rec, extra in writes:
            details = {k: rec[k] for k in WRITE_FACTS} | {"restore": self.rid} | extra
            audit.record("write.object", drive=self.session.id, details=details)
        if intent:
            self.batch += 1
            message = INTENT.format(batch=self.batch)
            for i in seqs or ():
                items.setdefault(i, {})["message"] = message
                self._declared.add(i)
            audit.record(
                "restore.batch",
                drive=self.session.id,
                message=f"restore {self.rid}: about to write {len(intent)} object(s) "
                f"(batch {self.batch})",
                details={
                    "restore": self.rid,
                    "batch": self.batch,
                    "writes": self._intended(intent),
                },
            )
        if not items and not writes and not restore:
            return
        store = asyncio.to_thread(
            self.service.store.journal, self.rid, items, [rec for rec, _ in writes], restore
        )
        if intent:
            # The intent is durable in both before the batch's first write goes out.
            await asyncio.gather(store, asyncio.to_thread(audit.flush))
        else:
            await store

    def _intended(self, steps: list[RestoreStep]) -> list[dict[str, Any]]:
        """Each write of a batch with the old value it will replace if all goes well (the
        automatic backup's, or an earlier batch's planned write of the same object: a PDO
        procedure writes its COB-ID twice). Intents are committed in batch order."""
        values = self._planned
        out = []
        for step in steps:
            prior = values.get(step.address)
            out.append(
                {
                    "address": str(step.address),
                    "why": step.why,
                    "old_raw_hex": prior.hex() if prior is not None else None,
                    "new_raw_hex": step.raw.hex(),
                }
            )
            values[step.address] = step.raw
        return out


def _step_dict(s: RestoreStep) -> dict[str, Any]:
    return {
        "address": str(s.address),
        "raw_hex": s.raw.hex(),
        "entry": str(s.entry) if s.entry is not None else None,
        "why": s.why,
    }


def _item_dict(it: restore_plan.PlanItem, pending: bool = False) -> dict[str, Any]:
    status = "pending" if pending and it.status == "would_write" else it.status
    return {
        "address": str(it.address),
        "source": str(it.source),
        "name": it.name,
        "status": status,
        "old_raw_hex": it.old_raw.hex() if it.old_raw is not None else None,
        "new_raw_hex": it.new_raw.hex() if it.new_raw is not None else None,
        "message": it.message,
    }
