/**
 * A failed read or write, the way every page should show a code: what failed, the server's
 * message, the protocol code in hex with its meaning, the profile's name, cause and remedy for
 * that code (when the manual gives them), and what to do.
 */
import type { Failure } from '../lib/codes';
import { protocolName } from '../state/notify';

export function FailureBox({ f, testid = 'failure' }: { f: Failure; testid?: string }) {
  const info = f.info;
  return (
    <div className="failure" role="alert" data-testid={testid}>
      <div className="failure-title">{f.action} failed</div>
      <div data-testid={`${testid}-message`}>{f.message}</div>
      {(f.code_hex || f.meaning) && (
        <div className="failure-code">
          {f.protocol ? `${protocolName(f.protocol)} ` : 'Code '}
          {f.code_hex && (
            <span className="mono" data-testid={`${testid}-code`}>
              {f.code_hex}
            </span>
          )}
          {(f.meaning || info?.name) && (
            <>
              {': '}
              <span data-testid={`${testid}-meaning`}>{f.meaning ?? info?.name}</span>
            </>
          )}
        </div>
      )}
      {info && <CodeInfo info={info} testid={testid} />}
      {f.hint && (
        <div className="notice-hint" data-testid={`${testid}-hint`}>
          <span className="hint-label">What to do:</span> {f.hint}
        </div>
      )}
    </div>
  );
}

/** Name, cause, remedy and manual section of a code from the profile's error tables. */
export function CodeInfo({ info, testid = 'code' }: { info: import('../api/types').ErrorInfo; testid?: string }) {
  return (
    <div className="code-info" data-testid={`${testid}-info`}>
      <div>
        <span className="mono">{info.display ?? info.code_hex}</span> <strong>{info.name}</strong>
        {info.kind ? <span className="muted"> · {info.kind}</span> : null}
      </div>
      {info.cause && (
        <div data-testid={`${testid}-cause`}>
          <span className="hint-label">Cause:</span> {info.cause}
        </div>
      )}
      {info.remedy && (
        <div data-testid={`${testid}-remedy`}>
          <span className="hint-label">Remedy:</span> {info.remedy}
        </div>
      )}
      {info.section && <div className="muted small">Manual: {info.section}</div>}
    </div>
  );
}
