import { renderToStaticMarkup } from 'react-dom/server';
import { describe, expect, it } from 'vitest';
import type { ScopeChannelConfig } from '../../api/scope';
import type { SessionInfo } from '../../api/types';
import { Observable } from '../../state/observable';
import { ChannelTable, MAX_CHANNELS } from './ChannelTable';
import { EMPTY_SUMMARY, type ScopeSummary } from './live';
import { channelColour } from './prefs';

/** 4 drives x 8 channels, as issue 50's 32-channel scope holds them. */
const DRIVES = ['cia402-generic-1', 'hiwin-e-2', 'smartris-3', 'lecsn-t-1'];

function channels(n: number): ScopeChannelConfig[] {
  return Array.from({ length: n }, (_, id) => ({
    id,
    session: DRIVES[Math.floor(id / 8)] ?? 'cia402-generic-1',
    address: '0x6064:00',
    source: 'sdo' as const,
    scale: 1,
    offset: 0,
    visible: true,
    label: null,
  }));
}

/** The table as the server would render it (the tests run without a DOM: the markup is read). */
function render(list: ScopeChannelConfig[], motionToAdd: readonly string[] = []): string {
  return renderToStaticMarkup(
    <ChannelTable
      channels={list}
      info={() => ({ status: null, object: null, unit: '', rawUnit: '' })}
      summary={new Observable<ScopeSummary>(EMPTY_SUMMARY)}
      sessions={DRIVES.map((id) => ({ id }) as SessionInfo)}
      objectsOf={() => null}
      recordableOf={() => new Set()}
      colourOf={(id) => channelColour({ colours: {}, maths: [] }, id)}
      onChange={() => {}}
      onColour={() => {}}
      onRemove={() => {}}
      onAdd={() => {}}
      onAddMotion={() => {}}
      motionToAdd={motionToAdd}
      busy={false}
    />,
  );
}

/** The opening tag of the element with this test id. */
function tag(html: string, testid: string): string {
  const m = new RegExp(`<[a-z]+[^>]*data-testid="${testid}"[^>]*>`).exec(html);
  if (!m) throw new Error(`no element ${testid}`);
  return m[0];
}

describe('the channel table', () => {
  it('lists 32 channels of 4 drives, each with its own colour, in a box that scrolls', () => {
    const html = render(channels(32));
    const rows = [...html.matchAll(/<tr[^>]*data-testid="scope-channel-(\d+)"/g)].map((m) => Number(m[1]));
    expect(rows).toEqual(channels(32).map((c) => c.id));
    const colours = rows.map((id) => /value="(#[0-9a-f]{6})"/.exec(tag(html, `scope-channel-${id}-colour`))?.[1]);
    expect(new Set(colours).size).toBe(32);
    // Each row names its drive: every one of the four is chosen in some row.
    for (const d of DRIVES) expect(html).toContain(`<option value="${d}" selected="">`);
    // The rows are inside their own scrolling box, the buttons after it.
    const box = html.indexOf('data-testid="scope-channel-rows"');
    const end = html.indexOf('</table>', box);
    expect(box).toBeGreaterThan(0);
    expect(html.indexOf('data-testid="scope-channel-31"')).toBeLessThan(end);
    expect(html.indexOf('data-testid="scope-add-channel"')).toBeGreaterThan(end);
    expect(html).toContain(`32 of ${MAX_CHANNELS} channels`);
  });

  it('offers another channel up to 32, and the motion channels only while one is free', () => {
    const disabled = (html: string, testid: string) => / disabled=""/.test(tag(html, testid));
    const some = render(channels(31), ['0x6064:00']);
    expect(disabled(some, 'scope-add-channel')).toBe(false);
    expect(disabled(some, 'scope-add-motion')).toBe(false);
    const full = render(channels(32), []);
    expect(disabled(full, 'scope-add-channel')).toBe(true);
    expect(disabled(full, 'scope-add-motion')).toBe(true);
  });
});
