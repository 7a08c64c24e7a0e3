/**
 * Scope (issue 7, docs/scope.md): up to 32 channels (4 drives x 8; issue 50's target is a 10 s
 * window of 32 channels at 4 kHz drawn at >= 30 fps) from one or several drives on the backend's
 * common time base, streamed over the binary WebSocket and drawn with uPlot, decimated in a
 * worker; the channel table scrolls inside its card and every channel has a colour of its own
 * (8 hues x 4 tones, components/scope/prefs.ts); triggers (roll, single, normal on a level, an
 * edge, a state change or a fault) with pre-trigger; zoom, pan, two cursors, per-trace
 * measurements of the visible range, math channels; export as CSV, MDF4 and PNG, and import of
 * a recording back into the view; captures kept in the store with a title and note, listed per
 * drive, opened, exported and attached to the drive's report
 * (issue 49, components/scope/KeptCaptures.tsx).
 *
 * The scope belongs to the application: this page shows and edits the one scope of the server
 * (another browser sees the same channels), opened from a drive's page so a new channel starts
 * on that drive. Colours and math channels stay in this browser.
 */
import { useCallback, useEffect, useMemo, useRef, useState } from 'react';
import {
  type ScopeChannelConfig,
  type ScopeChannelStatus,
  type ScopeExportFormat,
  type ScopeRecording,
  type ScopeStatus,
  type ScopeTrigger,
  scopeApi,
} from '../api/scope';
import type { ObjectInfo, ProfileDetail } from '../api/types';
import { FailureBox } from '../components/FailureBox';
import { saveBlob } from '../components/pdo/download';
import { KeptCaptures } from '../components/scope/KeptCaptures';
import { ChannelTable, type ChannelRowInfo, MAX_CHANNELS, MOTION_SET } from '../components/scope/ChannelTable';
import { EMPTY_SUMMARY, LiveMeasurements, type ScopeSummary, SkippedBadge, ViewLine } from '../components/scope/live';
import { MathPanel } from '../components/scope/MathPanel';
import { ScopeModel, type TraceDef, type ViewKind } from '../components/scope/model';
import { type Overlay, type PlotApi, ScopePlot } from '../components/scope/ScopePlot';
import { type RecordingMeta, normaliseRecording } from '../components/scope/recording';
import { MATH_COLOURS, MAX_MATH, type MathDef, type ScopePrefs, channelColour, loadPrefs, savePrefs } from '../components/scope/prefs';
import { type ShownTransform, TriggerPanel, levelToShown, slopeToRaw } from '../components/scope/TriggerPanel';
import { num, secs } from '../components/scope/format';
import { mathLabel, mathUnit } from '../components/scope/math';
import { openScopeStream } from '../components/scope/stream';
import { decodeFrame } from '../scope/wire';
import '../components/scope/scope.css';
import { type Failure, failureOf } from '../lib/codes';
import { isIntegerType } from '../lib/format';
import { Observable, useObservable } from '../state/observable';
import { loadSessionProfile } from '../state/profileCache';
import { sessions } from '../state/store';
import type { PageProps } from './registry';

/** Debounce of channel and trigger edits before they go to the server. */
const PUSH_DELAY_MS = 350;
/** How often the measurements and newest values are recomputed (they read the stored samples). */
const SUMMARY_PERIOD_MS = 250;

const DEFAULT_TRIGGER: ScopeTrigger = { mode: 'roll', kind: 'level', channel: 0, level: 0, slope: 'rising', pre: 0.2, window_s: 10, holdoff_s: 0 };

const STATE_TEXT: Record<string, string> = {
  idle: 'stopped',
  rolling: 'rolling',
  armed: 'armed: waiting for the trigger',
  triggered: 'triggered: recording the rest of the window',
  done: 'captured',
};

function configOf(c: ScopeChannelStatus): ScopeChannelConfig {
  return {
    id: c.id,
    session: c.session,
    address: c.address,
    source: c.requested_source ?? 'auto',
    scale: c.scale ?? 1,
    offset: c.offset ?? 0,
    visible: c.visible !== false,
    label: c.label ?? '',
    rate_hz: c.requested_rate_hz ?? 0,
  };
}

function sameChannels(a: readonly ScopeChannelConfig[], b: readonly ScopeChannelConfig[]): boolean {
  const key = (c: ScopeChannelConfig) =>
    [c.id, c.session, c.address.toUpperCase(), c.source, c.scale, c.offset, c.visible, c.label ?? '', c.rate_hz ?? 0].join('|');
  return a.length === b.length && a.every((c, i) => key(c) === key(b[i] as ScopeChannelConfig));
}

/** What the server needs of the drafts: channels with an object (label null when empty). */
function toServer(drafts: readonly ScopeChannelConfig[]): ScopeChannelConfig[] {
  return drafts.filter((c) => c.address).map((c) => ({ ...c, label: c.label ? c.label : null, rate_hz: c.rate_hz ?? 0 }));
}

declare global {
  interface Window {
    /** The scope page's model, for the browser test and the frame-rate benchmark. */
    __servodeskScope?: {
      model: ScopeModel;
      openRecording: (rec: import('../api/scope').ScopeRecording, name?: string) => void;
      /** A binary frame as the socket would deliver it (the benchmark's stream of 32 channels). */
      ingestFrame: (data: ArrayBuffer) => void;
      /** Traces to show in place of the server's channels (null: the server's again). */
      setTraces: (traces: TraceDef[] | null) => void;
    };
  }
}

export function ScopePage({ sid }: PageProps) {
  const [model] = useState(() => new ScopeModel());
  const sessionList = useObservable(sessions) ?? [];
  const [status, setStatus] = useState<ScopeStatus | null>(null);
  const [drafts, setDrafts] = useState<ScopeChannelConfig[] | null>(null);
  const [trigger, setTrigger] = useState<ScopeTrigger | null>(null);
  const [prefs, setPrefs] = useState<ScopePrefs>(loadPrefs);
  const [profiles, setProfiles] = useState<Map<string, ProfileDetail>>(new Map());
  const [recordable, setRecordable] = useState<Map<string, Set<string>>>(new Map());
  const [failure, setFailure] = useState<Failure | null>(null);
  const [channelFailure, setChannelFailure] = useState<Failure | null>(null);
  const [triggerFailure, setTriggerFailure] = useState<Failure | null>(null);
  const [connected, setConnected] = useState(false);
  const [wireError, setWireError] = useState<string | null>(null);
  const [recMeta, setRecMeta] = useState<RecordingMeta[] | null>(null);
  const [recName, setRecName] = useState<string | null>(null);
  const [hidden, setHidden] = useState<Set<string>>(new Set());
  const [injectedTraces, setInjectedTraces] = useState<TraceDef[] | null>(null);
  // The data-driven parts read this; the page itself re-renders only when the view changes.
  const [summary] = useState(() => new Observable<ScopeSummary>(EMPTY_SUMMARY));
  const [view, setView] = useState<ViewKind>('live');
  const [placing, setPlacing] = useState<'a' | 'b'>('a');
  const [busy, setBusy] = useState<string | null>(null);
  const plotApi = useRef<PlotApi | null>(null);
  const overlay = useRef<Overlay>({ level: null });
  const fileInput = useRef<HTMLInputElement | null>(null);

  // Pending edits: the server's pushes do not overwrite what the user is changing.
  const channelTimer = useRef<ReturnType<typeof setTimeout> | null>(null);
  const channelPending = useRef<Promise<void> | null>(null);
  const channelDirty = useRef(false);
  const triggerTimer = useRef<ReturnType<typeof setTimeout> | null>(null);
  const triggerPending = useRef<Promise<void> | null>(null);
  const triggerDirty = useRef(false);
  const draftsRef = useRef<ScopeChannelConfig[] | null>(null);
  draftsRef.current = drafts;
  const triggerRef = useRef<ScopeTrigger | null>(null);
  triggerRef.current = trigger;
  const shownCapture = useRef<number | null>(null);
  const viewRef = useRef<ViewKind>('live');

  const adoptStatus = useCallback((st: ScopeStatus) => {
    setStatus(st);
    if (!channelDirty.current) {
      const next = st.channels.map(configOf);
      const cur = draftsRef.current;
      // Keep rows the user is still choosing an object for.
      const choosing = (cur ?? []).filter((c) => !c.address && !next.some((n) => n.id === c.id));
      if (!cur || !sameChannels(cur.filter((c) => c.address), next)) setDrafts([...next, ...choosing].sort((x, y) => x.id - y.id));
    }
    if (!triggerDirty.current) setTrigger(st.trigger);
  }, []);

  // ------------------------------------------------------------------------------ loading

  const openCapture = useCallback(async () => {
    try {
      const rec = await scopeApi.capture();
      const n = normaliseRecording(rec);
      setRecMeta(n.meta);
      setRecName(null);
      // The frame may have opened it already: keep the user's zoom and cursors then.
      if (shownCapture.current !== n.open.triggerTime || model.kind !== 'capture') model.openRecording(n.open, 'capture');
      shownCapture.current = n.open.triggerTime;
    } catch (e) {
      setFailure(failureOf(e, 'Load the captured window'));
    }
  }, [model]);

  useEffect(() => {
    let live = true;
    scopeApi.status().then(
      (st) => live && adoptStatus(st),
      (e: unknown) => live && setFailure(failureOf(e, 'Read the scope')),
    );
    const prevState = { v: '' };
    const stop = openScopeStream(model, {
      status: (st) => {
        if (!live) return;
        adoptStatus(st);
        // A capture finished: open it (the capture frame does too; this covers a reconnect).
        if ((st.state === 'done' || st.state === 'armed') && prevState.v === 'triggered') void openCapture();
        prevState.v = st.state;
      },
      capture: () => {
        shownCapture.current = model.triggerTime;
        void openCapture();
      },
      connected: (open) => live && setConnected(open),
      error: (m) => live && setWireError(m),
    });
    window.__servodeskScope = {
      model,
      openRecording: (rec, name) => {
        const n = normaliseRecording(rec, name ?? 'injected');
        model.openRecording(n.open, 'recording');
        setRecMeta(n.meta);
        setRecName(name ?? 'injected');
      },
      ingestFrame: (data) => model.ingest(decodeFrame(data)),
      setTraces: setInjectedTraces,
    };
    return () => {
      live = false;
      stop();
      if (window.__servodeskScope?.model === model) delete window.__servodeskScope;
    };
  }, [model, adoptStatus, openCapture]);

  // Profiles of the sessions in use (units, scales, the object lists of the pickers).
  const usedSessions = useMemo(() => {
    const s = new Set<string>([sid]);
    for (const c of drafts ?? []) s.add(c.session);
    return [...s];
  }, [sid, drafts]);
  useEffect(() => {
    for (const s of usedSessions) {
      const info = sessionList.find((x) => x.id === s);
      if (!info || profiles.has(s)) continue;
      loadSessionProfile(info).then(
        (p) => setProfiles((m) => (m.has(s) ? m : new Map(m).set(s, p))),
        () => {},
      );
      scopeApi.recorder(s).then(
        (r) => setRecordable((m) => new Map(m).set(s, new Set(r.present ? r.objects.map((a) => a.toUpperCase()) : []))),
        () => setRecordable((m) => new Map(m).set(s, new Set())),
      );
    }
  }, [usedSessions, sessionList, profiles]);

  const objectOf = useCallback(
    (session: string, address: string): ObjectInfo | null =>
      profiles.get(session)?.object_list.find((o) => o.address.toUpperCase() === address.toUpperCase()) ?? null,
    [profiles],
  );

  // ------------------------------------------------------------------------------ edits

  const pushChannels = useCallback(
    (next: ScopeChannelConfig[]) => {
      setDrafts(next);
      channelDirty.current = true;
      if (channelTimer.current) clearTimeout(channelTimer.current);
      channelTimer.current = setTimeout(() => {
        channelTimer.current = null;
        const send = toServer(next);
        channelPending.current = scopeApi.setChannels(send).then(
          (st) => {
            channelDirty.current = channelTimer.current !== null;
            setChannelFailure(null);
            setStatus(st);
          },
          (e: unknown) => {
            // Keep the refused rows on screen (the server kept its old channels) until the
            // user changes them: the failure names what to fix.
            channelDirty.current = true;
            setChannelFailure(failureOf(e, 'Set the scope channels'));
          },
        );
      }, PUSH_DELAY_MS);
    },
    [],
  );

  const editChannel = (id: number, patch: Partial<ScopeChannelConfig>) => {
    const cur = drafts ?? [];
    const before = cur.find((c) => c.id === id);
    if (before && (patch.session !== undefined || patch.address !== undefined || patch.source !== undefined)) {
      const changed = (patch.session ?? before.session) !== before.session || (patch.address ?? before.address) !== before.address || (patch.source ?? before.source) !== before.source;
      if (changed) model.clearLive([id]);
    }
    pushChannels(cur.map((c) => (c.id === id ? { ...c, ...patch } : c)));
  };

  const addChannel = () => {
    const cur = drafts ?? [];
    if (cur.length >= MAX_CHANNELS) return;
    let id = 0;
    while (cur.some((c) => c.id === id)) id++;
    const last = cur[cur.length - 1];
    const next: ScopeChannelConfig = { id, session: last?.session ?? sid, address: '', source: 'auto', scale: 1, offset: 0, visible: true, label: '', rate_hz: 0 };
    setDrafts([...cur, next].sort((x, y) => x.id - y.id));
  };

  /** The motion channels of this page's drive that the profile has and the scope does not
   * show yet, as many as fit: one click to what a commissioning engineer looks at first. */
  const motionSet = (): string[] => {
    const have = new Set((drafts ?? []).filter((c) => c.session === sid).map((c) => c.address.toUpperCase()));
    return MOTION_SET.filter((a) => objectOf(sid, a) !== null && !have.has(a.toUpperCase()));
  };

  const addMotionSet = () => {
    const cur = drafts ?? [];
    const next = [...cur];
    for (const address of motionSet()) {
      if (next.length >= MAX_CHANNELS) break;
      let id = 0;
      while (next.some((c) => c.id === id)) id++;
      next.push({ id, session: sid, address, source: 'auto', scale: 1, offset: 0, visible: true, label: '', rate_hz: 0 });
    }
    if (next.length > cur.length) pushChannels(next.sort((x, y) => x.id - y.id));
  };

  const removeChannel = (id: number) => {
    model.clearLive([id]);
    pushChannels((drafts ?? []).filter((c) => c.id !== id));
  };

  // The scope is one capture for all drives (services/scope.py). Channels of other drives than
  // this page's are said so, with their drives, and kept only when the user chooses to
  // (issue 48: the LECSN-T page showed the generic drive's channels as its own).
  const others = (drafts ?? []).filter((c) => c.session !== sid);
  const otherDrives = [...new Set(others.map((c) => c.session))];
  const othersKey = `${sid}|${others.map((c) => `${c.id}:${c.session}`).join(',')}`;
  const [keptOthers, setKeptOthers] = useState<string | null>(() => sessionStorage.getItem(`servodesk.scope.kept.${sid}`));
  const keepOthers = () => {
    sessionStorage.setItem(`servodesk.scope.kept.${sid}`, othersKey);
    setKeptOthers(othersKey);
  };
  const removeOthers = () => {
    model.clearLive(others.map((c) => c.id));
    pushChannels((drafts ?? []).filter((c) => c.session === sid));
  };

  const pushTrigger = useCallback((next: ScopeTrigger) => {
    setTrigger(next);
    triggerDirty.current = true;
    if (triggerTimer.current) clearTimeout(triggerTimer.current);
    triggerTimer.current = setTimeout(() => {
      triggerTimer.current = null;
      triggerPending.current = scopeApi.setTrigger(next).then(
        (st) => {
          triggerDirty.current = triggerTimer.current !== null;
          setTriggerFailure(null);
          setStatus(st);
        },
        (e: unknown) => {
          triggerDirty.current = triggerTimer.current !== null;
          setTriggerFailure(failureOf(e, 'Set the trigger'));
        },
      );
    }, PUSH_DELAY_MS);
  }, []);

  /** Send what is waiting now (before run, arm and export). */
  const flush = async () => {
    if (channelTimer.current) {
      clearTimeout(channelTimer.current);
      channelTimer.current = null;
      const send = toServer(draftsRef.current ?? []);
      channelPending.current = scopeApi.setChannels(send).then(
        (st) => {
          channelDirty.current = false;
          setChannelFailure(null);
          setStatus(st);
        },
        (e: unknown) => {
          setChannelFailure(failureOf(e, 'Set the scope channels'));
          throw e;
        },
      );
    }
    if (triggerTimer.current && triggerRef.current) {
      clearTimeout(triggerTimer.current);
      triggerTimer.current = null;
      triggerPending.current = scopeApi.setTrigger(triggerRef.current).then(
        (st) => {
          triggerDirty.current = false;
          setTriggerFailure(null);
          setStatus(st);
        },
        (e: unknown) => {
          setTriggerFailure(failureOf(e, 'Set the trigger'));
          throw e;
        },
      );
    }
    await channelPending.current;
    await triggerPending.current;
  };

  const updatePrefs = (fn: (p: ScopePrefs) => ScopePrefs) =>
    setPrefs((p) => {
      const next = fn(p);
      savePrefs(next);
      return next;
    });

  // ------------------------------------------------------------------------------ traces

  const channels = useMemo(() => (drafts ?? []).filter((c) => c.address), [drafts]);
  const statusOf = useCallback((id: number) => status?.channels.find((c) => c.id === id) ?? null, [status]);

  const traces: TraceDef[] = useMemo(() => {
    if (injectedTraces) return injectedTraces;
    const defs: TraceDef[] = [];
    const kind = view;
    if (kind === 'recording' && recMeta) {
      for (const m of recMeta) {
        const key = `c${m.id}`;
        defs.push({
          key,
          kind: 'channel',
          id: m.id,
          label: m.label,
          colour: channelColour(prefs, m.id),
          visible: !hidden.has(key),
          unit: m.unit,
          rawUnit: m.rawUnit,
          engScale: m.engScale,
          scale: m.scale,
          offset: m.offset,
        });
      }
    } else {
      for (const c of channels) {
        const st = statusOf(c.id);
        const obj = objectOf(c.session, c.address);
        const cap = kind === 'capture' ? recMeta?.find((m) => m.id === c.id) : undefined;
        defs.push({
          key: `c${c.id}`,
          kind: 'channel',
          id: c.id,
          label: c.label || st?.name || obj?.name || c.address,
          colour: channelColour(prefs, c.id),
          visible: c.visible,
          unit: st?.unit ?? obj?.unit ?? cap?.unit ?? '',
          rawUnit: st?.raw_unit ?? obj?.raw_unit ?? cap?.rawUnit ?? '',
          engScale: st?.eng_scale ?? obj?.scale ?? cap?.engScale ?? 1,
          scale: c.scale,
          offset: c.offset,
        });
      }
    }
    for (const m of prefs.maths) {
      const A = defs.find((d) => d.kind === 'channel' && d.id === m.a);
      const B = m.b === null ? undefined : defs.find((d) => d.kind === 'channel' && d.id === m.b);
      if (!A) continue;
      const key = `m${m.id}`;
      defs.push({
        key,
        kind: 'math',
        id: m.id,
        label: `M${m.id}: ${mathLabel(m.op, A.label, B?.label ?? null)}`,
        colour: m.colour,
        visible: m.visible,
        unit: mathUnit(m.op, A.unit, B?.unit ?? null),
        rawUnit: mathUnit(m.op, A.rawUnit || 'raw', B ? B.rawUnit || 'raw' : null),
        engScale: 1,
        scale: 1,
        offset: 0,
        op: m.op,
        a: m.a,
        b: m.b,
      });
    }
    return defs;
  }, [view, recMeta, channels, statusOf, objectOf, prefs, hidden, injectedTraces]);

  useEffect(() => model.setTraces(traces), [model, traces]);

  const transformOf = useCallback(
    (id: number): ShownTransform => {
      const d = traces.find((t) => t.kind === 'channel' && t.id === id);
      const c = (drafts ?? []).find((x) => x.id === id);
      const integer = c ? isIntegerType(objectOf(c.session, c.address)?.data_type) : false;
      return d ? { a: d.engScale * d.scale, b: d.offset, unit: d.unit, rawUnit: d.rawUnit, integer } : { a: 1, b: 0, unit: '', rawUnit: '', integer };
    },
    [traces, drafts, objectOf],
  );

  // Reset zoom follows the newest samples while the scope runs, shows the whole run after Stop.
  useEffect(() => {
    model.setRunning(status?.running ?? false);
  }, [model, status?.running]);

  // Live span and the trigger level line.
  useEffect(() => {
    if (!trigger) return;
    const tr = transformOf(trigger.channel);
    overlay.current.level =
      trigger.mode !== 'roll' && trigger.kind === 'level' ? { key: `c${trigger.channel}`, value: levelToShown('level', trigger.level, tr) } : null;
    model.span = trigger.window_s;
    model.changed();
  }, [model, trigger, transformOf]);

  // Measurements and newest values, a few times a second, only when something changed.
  useEffect(() => {
    let seen = -1;
    const tick = () => {
      if (model.version === seen) return;
      seen = model.version;
      const latest = new Map<number, { shown: number; raw: number }>();
      for (const d of model.traces) {
        if (d.kind !== 'channel') continue;
        const s = model.live.get(d.id);
        if (s && s.n) {
          const raw = s.v[s.n - 1] as number;
          latest.set(d.id, { raw, shown: d.engScale * d.scale * raw + d.offset });
        }
      }
      let chans = 0;
      for (const s of (model.kind === 'live' ? model.live : model.recording).values()) if (s.n) chans++;
      if (model.kind !== viewRef.current) {
        viewRef.current = model.kind;
        setView(model.kind);
      }
      summary.set({
        window: model.window(),
        stats: model.stats(),
        a: model.cursorA === null ? null : model.valuesAt(model.cursorA),
        b: model.cursorB === null ? null : model.valuesAt(model.cursorB),
        cursorA: model.cursorA,
        cursorB: model.cursorB,
        kind: model.kind,
        samples: model.sampleCount(),
        channels: chans,
        skipped: model.skipped,
        latest,
      });
    };
    tick();
    const t = setInterval(tick, SUMMARY_PERIOD_MS);
    return () => clearInterval(t);
  }, [model, summary]);

  // ------------------------------------------------------------------------------ actions

  async function run(action: 'start' | 'stop' | 'arm') {
    setBusy(action);
    setFailure(null);
    try {
      await flush();
      if (action !== 'stop') {
        model.clearLive();
        if (model.kind === 'recording' || action === 'start') {
          model.showLive();
          setRecMeta(null);
          setRecName(null);
        }
      }
      const tr = triggerRef.current;
      if (action !== 'stop' && tr && tr.mode !== 'roll') shownCapture.current = null;
      adoptStatus(await scopeApi.run(action));
    } catch (e) {
      setFailure(failureOf(e, { start: 'Start the scope', stop: 'Stop the scope', arm: 'Arm the trigger' }[action]));
    } finally {
      setBusy(null);
    }
  }

  async function doExport(format: ScopeExportFormat) {
    setFailure(null);
    setBusy(`export-${format}`);
    try {
      await flush();
      const f = await scopeApi.export(format, model.kind === 'capture' ? 'capture' : 'buffer');
      saveBlob(f.blob, f.filename ?? `scope.${format === 'mdf4' ? 'mf4' : 'csv'}`);
    } catch (e) {
      setFailure(failureOf(e, `Export as ${format === 'csv' ? 'CSV' : 'MDF4'}`));
    } finally {
      setBusy(null);
    }
  }

  async function doPng() {
    setFailure(null);
    const api = plotApi.current;
    if (!api) return;
    const [x0, x1] = model.window();
    const what = model.kind === 'live' ? 'live' : model.kind === 'capture' ? 'capture (trigger at 0 s)' : `recording ${recName ?? ''}`;
    const title = `servodesk scope · ${what} · ${secs(x0)} … ${secs(x1)} · ${new Date().toLocaleString()}`;
    const atA = model.cursorA === null ? [] : model.valuesAt(model.cursorA);
    const atB = model.cursorB === null ? [] : model.valuesAt(model.cursorB);
    const legend = model.traces
      .filter((t) => t.visible)
      .map((t) => {
        const a = atA.find((c) => c.key === t.key);
        const b = atB.find((c) => c.key === t.key);
        const unit = t.unit ? ` ${t.unit}` : '';
        let text = `${t.label}${t.unit ? ` [${t.unit}]` : ''}`;
        if (t.kind === 'channel' && (t.scale !== 1 || t.offset !== 0)) text += ` (×${num(t.scale)} ${t.offset >= 0 ? '+' : '−'} ${num(Math.abs(t.offset))})`;
        if (a) text += `   A: ${num(a.shown)}${unit} (raw ${num(a.raw, 10)})`;
        if (b) text += `   B: ${num(b.shown)}${unit} (raw ${num(b.raw, 10)})`;
        return { colour: t.colour, text };
      });
    if (model.cursorA !== null && model.cursorB !== null) {
      const dt = model.cursorB - model.cursorA;
      legend.push({ colour: '#ffffff', text: `Δt = ${secs(dt)}   1/Δt = ${dt ? num(1 / Math.abs(dt)) : '—'} Hz` });
    }
    const blob = await api.png(title, legend);
    if (!blob) {
      setFailure(failureOf(new Error('the browser could not draw the image'), 'Save the view as PNG'));
      return;
    }
    const stamp = new Date().toISOString().replace(/[:.]/g, '-').slice(0, 19);
    saveBlob(blob, `scope-${model.kind}-${stamp}.png`);
  }

  async function doImport(file: File) {
    setFailure(null);
    setBusy('import');
    try {
      const bytes = await file.arrayBuffer();
      const rec = await scopeApi.import(file.name, bytes);
      const n = normaliseRecording(rec, file.name);
      model.openRecording(n.open, 'recording');
      setRecMeta(n.meta);
      setRecName(file.name);
      setHidden(new Set());
    } catch (e) {
      setFailure(failureOf(e, `Import ${file.name}`));
    } finally {
      setBusy(null);
      if (fileInput.current) fileInput.current.value = '';
    }
  }

  /** A kept capture (the store's) opened in the plot as a recording, like an imported file. */
  const openKept = useCallback(
    (rec: ScopeRecording, name: string) => {
      const n = normaliseRecording(rec, name);
      model.openRecording(n.open, 'recording');
      setRecMeta(n.meta);
      setRecName(name);
      setHidden(new Set());
    },
    [model],
  );

  const placeCursor = useCallback(
    (x: number) => {
      setPlacing((which) => {
        model.setCursor(which, x);
        return which === 'a' ? 'b' : 'a';
      });
    },
    [model],
  );

  const toggleTrace = (key: string) => {
    const t = traces.find((x) => x.key === key);
    if (!t) return;
    if (t.kind === 'math') updatePrefs((p) => ({ ...p, maths: p.maths.map((m) => (m.id === t.id ? { ...m, visible: !m.visible } : m)) }));
    else if (view === 'recording') setHidden((h) => (h.has(key) ? new Set([...h].filter((k) => k !== key)) : new Set(h).add(key)));
    else editChannel(t.id, { visible: !t.visible });
  };

  // ------------------------------------------------------------------------------ render

  const rowInfo = (c: ScopeChannelConfig): ChannelRowInfo => {
    const st = statusOf(c.id);
    const obj = objectOf(c.session, c.address);
    const d = traces.find((t) => t.kind === 'channel' && t.id === c.id);
    return {
      status: st && st.address.toUpperCase() === c.address.toUpperCase() && st.session === c.session ? st : null,
      object: obj,
      unit: d?.unit ?? obj?.unit ?? '',
      rawUnit: d?.rawUnit ?? obj?.raw_unit ?? '',
    };
  };

  const state = status?.state ?? 'idle';
  const tr = trigger ?? status?.trigger ?? DEFAULT_TRIGGER;
  const channelChoices = channels.map((c) => ({ id: c.id, label: traces.find((t) => t.key === `c${c.id}`)?.label ?? c.address }));
  const exportWindow = view === 'capture' ? 'the captured window' : 'the live buffer';

  return (
    <div className="stack scope-page" data-testid="scope-page">
      {others.length > 0 && (
        <div className={keptOthers === othersKey ? 'muted small' : 'bk-warn small'} data-testid="scope-other-drives" data-kept={keptOthers === othersKey ? 'true' : 'false'}>
          This capture also holds {others.length} channel{others.length === 1 ? '' : 's'} of {otherDrives.length === 1 ? 'another drive' : 'other drives'}:{' '}
          {otherDrives.map((d, i) => (
            <span key={d}>
              {i > 0 ? ', ' : ''}
              <span className="mono">{d}</span> ({others.filter((c) => c.session === d).length})
            </span>
          ))}
          , not {sid}. {keptOthers === othersKey ? 'Kept in this capture as you chose; each row names its drive.' : 'One capture may record several drives, when you choose it.'}
          {keptOthers !== othersKey && (
            <span className="bk-row" style={{ marginTop: 4 }}>
              <button type="button" className="small-btn" onClick={keepOthers} data-testid="scope-other-keep">
                Keep them in this capture
              </button>
              <button type="button" className="small-btn" onClick={removeOthers} disabled={busy !== null} data-testid="scope-other-remove">
                Remove them: record {sid} only
              </button>
            </span>
          )}
        </div>
      )}
      <section className="card" data-testid="scope-main">
        <h2>
          Scope
          <span className="h2-side small">
            <span className={`scope-state scope-state-${state}`} data-testid="scope-state" data-state={state} data-running={String(status?.running ?? false)}>
              {STATE_TEXT[state] ?? state}
            </span>
            <span className="muted">
              {' '}
              · {status?.clients ?? 0} viewer{status?.clients === 1 ? '' : 's'} ·{' '}
            </span>
            <span className={connected ? 'scope-ok' : 'scope-warn'} data-testid="scope-connection" data-connected={String(connected)}>
              {connected ? 'stream connected' : 'stream not connected'}
            </span>
            <SkippedBadge summary={summary} />
          </span>
        </h2>
        <div className="scope-row scope-toolbar">
          <button type="button" className="scope-go" onClick={() => void run('start')} disabled={busy !== null || channels.length === 0} data-testid="scope-run" title="start sampling (a single or normal trigger is armed as well)">
            Run
          </button>
          <button type="button" onClick={() => void run('arm')} disabled={busy !== null || tr.mode === 'roll' || channels.length === 0} data-testid="scope-arm" title="wait for the trigger and capture a window">
            Arm
          </button>
          <button type="button" onClick={() => void run('stop')} disabled={busy !== null || !status?.running} data-testid="scope-stop">
            Stop
          </button>
          <span className="scope-sep" />
          <ViewLine summary={summary} name={recName} />
          {view !== 'live' && (
            <button
              type="button"
              className="small-btn"
              onClick={() => {
                model.showLive();
                setRecMeta(null);
                setRecName(null);
              }}
              data-testid="scope-back-live"
              title="back to the live samples"
            >
              Live
            </button>
          )}
          <span className="spacer" />
          <button type="button" className="small-btn" onClick={() => model.resetZoom()} data-testid="scope-reset-zoom" title={view === 'live' && status?.running ? 'follow the newest samples again' : view === 'live' ? 'show the whole run' : 'show the whole recording'}>
            Reset zoom
          </button>
          <span className="segmented" role="group" aria-label="cursor to place">
            <button type="button" className={placing === 'a' ? 'on' : ''} onClick={() => setPlacing('a')} data-testid="scope-place-a" title="a click in the plot places cursor A">
              A
            </button>
            <button type="button" className={placing === 'b' ? 'on' : ''} onClick={() => setPlacing('b')} data-testid="scope-place-b" title="a click in the plot places cursor B">
              B
            </button>
          </span>
          <button
            type="button"
            className="small-btn"
            onClick={() => {
              model.setCursor('a', null);
              model.setCursor('b', null);
              setPlacing('a');
            }}
            data-testid="scope-clear-cursors"
          >
            Clear cursors
          </button>
          <span className="scope-sep" />
          <button type="button" className="small-btn" disabled={busy !== null || view === 'recording'} onClick={() => void doExport('csv')} title={`${exportWindow} as CSV (time_s, one column per channel, raw values, units in the header)`} data-testid="scope-export-csv">
            CSV
          </button>
          <button type="button" className="small-btn" disabled={busy !== null || view === 'recording'} onClick={() => void doExport('mdf4')} title={`${exportWindow} as MDF4 (asammdf; engineering conversion and units per channel)`} data-testid="scope-export-mdf4">
            MDF4
          </button>
          <button type="button" className="small-btn" onClick={() => void doPng()} title="this view as a PNG image with its legend" data-testid="scope-export-png">
            PNG
          </button>
          <button type="button" className="small-btn" disabled={busy !== null} onClick={() => fileInput.current?.click()} title="open a CSV or MDF4 recording (exported here or by another tool)" data-testid="scope-import">
            Import…
          </button>
          <input
            ref={fileInput}
            type="file"
            accept=".csv,.mf4,.mdf"
            hidden
            onChange={(e) => {
              const f = e.target.files?.[0];
              if (f) void doImport(f);
            }}
            data-testid="scope-import-file"
          />
        </div>
        {failure && <FailureBox f={failure} testid="scope-failure" />}
        {wireError && (
          <div className="failure" role="alert" data-testid="scope-wire-error">
            A scope frame could not be read: {wireError}
          </div>
        )}
        <ScopePlot
          model={model}
          overlay={overlay}
          onPlaceCursor={placeCursor}
          onApi={(api) => {
            plotApi.current = api;
          }}
        />
        <div className="muted small scope-hint">
          Drag: zoom to a range · shift-drag or wheel: pan · ctrl+wheel: zoom around the pointer · click: place cursor {placing.toUpperCase()}
          {view === 'capture' && ' · the red dotted line is the trigger sample'}
        </div>
      </section>

      <KeptCaptures
        sid={sid}
        keepWindow={view === 'capture' ? 'capture' : 'buffer'}
        canKeep={channels.some((c) => c.session === sid) ? null : 'the scope has no channel of this drive: add one and record first'}
        onOpen={openKept}
      />

      <section className="card">
        <h2>Measurements of the visible range</h2>
        <LiveMeasurements traces={traces} summary={summary} onToggle={toggleTrace} />
      </section>

      <section className="card">
        <h2>
          Channels
          <span className="h2-side small muted">the scope is shared: every browser shows and edits the same channels</span>
        </h2>
        {channelFailure && <FailureBox f={channelFailure} testid="scope-channel-failure" />}
        {drafts === null ? (
          <div className="muted">Reading the scope…</div>
        ) : (
          <ChannelTable
            channels={drafts}
            info={rowInfo}
            summary={summary}
            sessions={sessionList}
            objectsOf={(s) => profiles.get(s)?.object_list ?? null}
            recordableOf={(s) => recordable.get(s) ?? new Set()}
            colourOf={(id) => channelColour(prefs, id)}
            onChange={editChannel}
            onColour={(id, colour) => updatePrefs((p) => ({ ...p, colours: { ...p.colours, [`c${id}`]: colour } }))}
            onRemove={removeChannel}
            onAdd={addChannel}
            onAddMotion={addMotionSet}
            motionToAdd={(drafts ?? []).length < MAX_CHANNELS ? motionSet() : []}
            busy={busy !== null}
          />
        )}
      </section>

      <div className="scope-two">
        <section className="card">
          <h2>Trigger</h2>
          {triggerFailure && <FailureBox f={triggerFailure} testid="scope-trigger-failure" />}
          <TriggerPanel
            trigger={tr}
            channels={channelChoices}
            transformOf={transformOf}
            onChange={(patch) => {
              const next = { ...tr, ...patch };
              // The server compares raw samples: a negative scale turns the shown slope around.
              if (patch.slope !== undefined) next.slope = slopeToRaw(patch.slope, transformOf(next.channel));
              pushTrigger(next);
            }}
          />
        </section>
        <section className="card">
          <h2>Math channels</h2>
          <MathPanel
            maths={prefs.maths}
            channels={channelChoices}
            onChange={(id, patch) => updatePrefs((p) => ({ ...p, maths: p.maths.map((m) => (m.id === id ? { ...m, ...patch } : m)) }))}
            onAdd={() =>
              updatePrefs((p) => {
                if (p.maths.length >= MAX_MATH) return p;
                let id = 0;
                while (p.maths.some((m) => m.id === id)) id++;
                const a = channelChoices[0]?.id ?? 0;
                const b = channelChoices[1]?.id ?? null;
                const m: MathDef = { id, op: b === null ? 'deriv' : 'diff', a, b, visible: true, colour: MATH_COLOURS[id % MATH_COLOURS.length] as string };
                return { ...p, maths: [...p.maths, m] };
              })
            }
            onRemove={(id) => updatePrefs((p) => ({ ...p, maths: p.maths.filter((m) => m.id !== id) }))}
          />
        </section>
      </div>
    </div>
  );
}
