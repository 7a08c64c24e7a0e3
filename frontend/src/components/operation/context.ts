/** What every motion panel of the Operation page needs to know about the drive and this tab. */
import type { DriveState, Limits } from '../../api/types';
import type { EntryUnits } from '../../lib/motionLimits';

export interface PanelContext {
  sid: string;
  /** The limits the backend enforces; null while loading or when they could not be read. */
  limits: Limits | null;
  entry: EntryUnits;
  state: DriveState | null;
  /** This tab holds control of the drive. */
  you: boolean;
  /** The WebSocket (with this tab's client id) is open: needed for the dead-man. */
  socketOpen: boolean;
}
