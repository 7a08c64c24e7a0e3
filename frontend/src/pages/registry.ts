/**
 * The page registry: every page of the UI (DESIGN.md "The browser UI"), in navigation order.
 *
 * A page with a `component` is shown in the navigation; the others are listed here so the
 * navigation's order and names are fixed now and a later page plugs in by adding its
 * component to its entry. `scope: 'session'` pages show one drive and take its session id
 * from the URL.
 */
import type { ComponentType } from 'react';
import { AlarmsPage } from './AlarmsPage';
import { AuditPage } from './AuditPage';
import { AxesPage } from './AxesPage';
import { BackupPage } from './BackupPage';
import { ConnectPage } from './ConnectPage';
import { FleetPage } from './FleetPage';
import { NetworkPage } from './NetworkPage';
import { ObjectAccessPage } from './ObjectAccessPage';
import { ObjectDictionaryPage } from './ObjectDictionaryPage';
import { OperationPage } from './OperationPage';
import { OverviewPage } from './OverviewPage';
import { ParametersPage } from './ParametersPage';
import { PdoPage } from './PdoPage';
import { ScopePage } from './ScopePage';
import { TuningPage } from './TuningPage';
import { UsersPage } from './UsersPage';
import { ViewerPage } from './ViewerPage';

export interface PageProps {
  /** The session the page shows (session-scoped pages only). */
  sid: string;
}

export interface PageDef {
  id: string;
  title: string;
  group: 'Bus' | 'Drive' | 'Data' | 'Service';
  scope: 'global' | 'session';
  /** One line shown as the page's subtitle and the navigation tooltip. */
  description: string;
  component?: ComponentType<PageProps>;
}

export const PAGES: readonly PageDef[] = [
  { id: 'connect', title: 'Connect', group: 'Bus', scope: 'global', description: 'Scan the bus and open drive sessions', component: ConnectPage },
  { id: 'axes', title: 'All axes', group: 'Bus', scope: 'global', description: 'Every open drive: state, position, velocity, alarm, backup, control', component: AxesPage },
  { id: 'network', title: 'Network configuration', group: 'Bus', scope: 'session', description: 'Station name, addresses, telegram, LEDs', component: NetworkPage },
  { id: 'overview', title: 'Overview', group: 'Drive', scope: 'session', description: 'Identity, state machine, statusword, live values', component: OverviewPage },
  { id: 'operation', title: 'Operation', group: 'Drive', scope: 'session', description: 'Servo on, jog, move, home with a dead-man', component: OperationPage },
  { id: 'tuning', title: 'Tuning', group: 'Drive', scope: 'session', description: 'Gains, one-touch tuning, Bode', component: TuningPage },
  { id: 'scope', title: 'Scope', group: 'Drive', scope: 'session', description: 'Triggered recording of process values', component: ScopePage },
  { id: 'alarms', title: 'Alarms', group: 'Drive', scope: 'session', description: 'Current alarm, history, causes and remedies', component: AlarmsPage },
  { id: 'parameters', title: 'Parameters', group: 'Data', scope: 'session', description: 'Grouped parameters, hex and units, save to EEPROM', component: ParametersPage },
  { id: 'objects', title: 'Object access', group: 'Data', scope: 'session', description: 'Read and write one object by address', component: ObjectAccessPage },
  { id: 'dictionary', title: 'Object dictionary', group: 'Data', scope: 'session', description: 'Every object of the profile', component: ObjectDictionaryPage },
  { id: 'pdo', title: 'PDO mapping', group: 'Data', scope: 'session', description: 'Process data layout the PLC needs', component: PdoPage },
  { id: 'fleet', title: 'Fleet', group: 'Data', scope: 'global', description: 'Every drive of every gateway: plant tag, approved backup, drift', component: FleetPage },
  { id: 'backup', title: 'Backup & restore', group: 'Service', scope: 'session', description: 'Back up, restore and compare parameters', component: BackupPage },
  { id: 'view3d', title: '3D view', group: 'Service', scope: 'session', description: 'Live 3D twin of the axes', component: ViewerPage },
  { id: 'audit', title: 'Audit log', group: 'Service', scope: 'global', description: 'Who did what, when, from where; hash-chained', component: AuditPage },
  { id: 'users', title: 'Users', group: 'Service', scope: 'global', description: 'Accounts, login sessions, API tokens', component: UsersPage },
];

/** The pages that work now, in navigation order. */
export const READY_PAGES: readonly PageDef[] = PAGES.filter((p) => p.component !== undefined);

export function findPage(id: string): PageDef | undefined {
  return READY_PAGES.find((p) => p.id === id);
}
