/**
 * The plot worker: a thin shell around PlotEngine (plotEngine.ts), so the min/max per pixel
 * column of up to millions of samples is computed off the page's main thread, which then
 * only draws. Started by plotFeed.ts.
 */
import { PlotEngine, type ToWorker } from './plotEngine';

const engine = new PlotEngine();

self.onmessage = (e: MessageEvent<ToWorker>) => {
  const reply = engine.handle(e.data);
  if (reply) (self as unknown as Worker).postMessage(reply, [reply.x.buffer, ...reply.ys.map((y) => y.buffer)]);
};
