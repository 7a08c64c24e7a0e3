/**
 * The left sidebar: the open drives (components/DriveTree: bus -> drive -> axis, with state,
 * alarm and who holds control) above the page links, which are generated from the page
 * registry (only pages that work are listed). The drives come first because the per-drive
 * links below act on the drive selected there: choose the drive, then what to do with it.
 */
import { READY_PAGES, type PageDef } from '../pages/registry';
import { routeHref } from '../state/router';
import { DriveTree } from './DriveTree';
import { ThemeToggle } from './ThemeToggle';

const GROUPS: ReadonlyArray<PageDef['group']> = ['Bus', 'Drive', 'Data', 'Service'];

export function Nav({ active, sid }: { active: string; sid: string | null }) {
  return (
    <div className="nav">
      <DriveTree active={active} />
      <nav aria-label="Pages">
        {GROUPS.map((g) => {
          const pages = READY_PAGES.filter((p) => p.group === g);
          if (pages.length === 0) return null;
          return (
            <div className="nav-group" key={g}>
              <div className="nav-group-title">{g}</div>
              {pages.map((p) => {
                const needsSid = p.scope === 'session';
                const href = routeHref(p.id, needsSid ? sid : null);
                return (
                  <a
                    key={p.id}
                    href={href}
                    className={`nav-item${p.id === active ? ' active' : ''}${needsSid && !sid ? ' dim' : ''}`}
                    data-testid={`nav-${p.id}`}
                    title={p.description}
                    aria-current={p.id === active ? 'page' : undefined}
                  >
                    {p.title}
                  </a>
                );
              })}
            </div>
          );
        })}
      </nav>
      <div className="nav-foot muted">
        <ThemeToggle />
        <div>
          API v1 · <a href="/docs" target="_blank" rel="noreferrer">/docs</a>
        </div>
      </div>
    </div>
  );
}
