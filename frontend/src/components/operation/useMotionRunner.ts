/**
 * Starting a motion from a panel: heartbeats begin before the request (the server's dead-man
 * counts from its arrival), the answer or the failure is recorded, and a failure is kept for
 * the panel to show with the server's message and hint (e.g. the 409 naming the client that
 * holds control).
 */
import { useCallback, useState } from 'react';
import type { MotionStatus } from '../../api/types';
import { type Failure, failureOf } from '../../lib/codes';
import { beginHeartbeat, startAnswered } from './operationStore';

export function useMotionRunner(sid: string) {
  const [failure, setFailure] = useState<Failure | null>(null);
  const [busy, setBusy] = useState(false);

  const run = useCallback(
    async (action: string, start: () => Promise<MotionStatus>): Promise<MotionStatus | null> => {
      setFailure(null);
      setBusy(true);
      beginHeartbeat(sid);
      try {
        const status = await start();
        startAnswered(sid, status);
        return status;
      } catch (e) {
        startAnswered(sid, null);
        setFailure(failureOf(e, action));
        return null;
      } finally {
        setBusy(false);
      }
    },
    [sid],
  );

  return { run, failure, setFailure, busy };
}
