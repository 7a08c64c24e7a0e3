/**
 * A windowed table: only the rows in view (plus a few) are in the DOM, so a 2912-object
 * dictionary filters and scrolls as fast as a 30-row one. Rows have one fixed height; the
 * space of the rows not drawn is held by two spacer rows so the scrollbar stays true and the
 * columns stay aligned with the sticky header.
 */
import { type ReactNode, type UIEvent, useEffect, useLayoutEffect, useRef, useState } from 'react';

export function VirtualTable({
  count,
  rowHeight,
  header,
  colgroup,
  renderRow,
  className = '',
  overscan = 8,
  scrollToRow = null,
  resetKey = '',
  testid,
  attrs,
}: {
  count: number;
  rowHeight: number;
  header: ReactNode;
  colgroup: ReactNode;
  renderRow: (i: number) => ReactNode;
  className?: string;
  overscan?: number;
  /** Scroll so this row is visible (e.g. after a filter change keeps the selection). */
  scrollToRow?: number | null;
  /** When this changes the table scrolls back to the top. */
  resetKey?: string;
  testid?: string;
  attrs?: Record<string, string>;
}) {
  const ref = useRef<HTMLDivElement>(null);
  const [scrollTop, setScrollTop] = useState(0);
  const [viewH, setViewH] = useState(600);

  useLayoutEffect(() => {
    const el = ref.current;
    if (!el) return;
    setViewH(el.clientHeight || 600);
    const ro = new ResizeObserver(() => setViewH(el.clientHeight || 600));
    ro.observe(el);
    return () => ro.disconnect();
  }, []);

  // A new result list (new filter) starts at the top.
  useEffect(() => {
    const el = ref.current;
    if (el && el.scrollTop !== 0) {
      el.scrollTop = 0;
      setScrollTop(0);
    }
  }, [resetKey]);

  useEffect(() => {
    const el = ref.current;
    if (!el || scrollToRow === null || scrollToRow < 0) return;
    const top = scrollToRow * rowHeight;
    if (top < el.scrollTop || top + rowHeight > el.scrollTop + el.clientHeight - rowHeight) {
      el.scrollTop = Math.max(0, top - el.clientHeight / 3);
    }
  }, [scrollToRow, rowHeight]);

  const onScroll = (e: UIEvent<HTMLDivElement>) => setScrollTop(e.currentTarget.scrollTop);

  const first = Math.max(0, Math.floor(scrollTop / rowHeight) - overscan);
  const last = Math.min(count, Math.ceil((scrollTop + viewH) / rowHeight) + overscan);
  const rows: ReactNode[] = [];
  for (let i = first; i < last; i++) rows.push(renderRow(i));
  return (
    <div className={`vt-scroll ${className}`} ref={ref} onScroll={onScroll} data-testid={testid} {...attrs}>
      <table className="grid vt-table">
        {colgroup}
        <thead>{header}</thead>
        <tbody>
          {first > 0 && <tr className="vt-spacer" style={{ height: first * rowHeight }} aria-hidden="true" />}
          {rows}
          {last < count && <tr className="vt-spacer" style={{ height: (count - last) * rowHeight }} aria-hidden="true" />}
        </tbody>
      </table>
    </div>
  );
}
