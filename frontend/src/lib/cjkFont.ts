/**
 * The shipped CJK subset ("Servodesk CJK", styles.css) loaded before the first render.
 *
 * Loading it on demand (its unicode-range alone) drew boxes: Chromium shapes a CJK text it
 * meets before the face has loaded with the system's fallback font (DejaVu Sans here, which
 * has no such glyphs) and keeps that fallback for the same characters at the same size and
 * weight after the face has arrived; the Parameters page's first group subtitle stayed boxes
 * while a group opened later was drawn right (seen with CSS.getPlatformFontsForNode; changing
 * the font lists did not clear it, a new weight did). Loaded first, the face is in place
 * before any text is shaped. Loading it does not change which font draws a character: the
 * systems' own CJK fonts stay ahead of it in --cjk. It costs one 75 kB file, cached.
 */
export const CJK_FAMILY = 'Servodesk CJK';
/** A character of the subset: load() fetches the faces whose unicode-range holds it. */
const PROBE = '保';
/** A slow or missing file never holds the UI back longer than this. */
const WAIT_MS = 1500;

export function loadCjkFont(doc: Document = document): Promise<void> {
  const fonts = doc.fonts as FontFaceSet | undefined;
  if (!fonts) return Promise.resolve();
  const loaded = fonts.load(`13px "${CJK_FAMILY}"`, PROBE).then(
    () => undefined,
    () => undefined, // No font: the names show as the system can, the UI still starts.
  );
  const timeout = new Promise<void>((resolve) => setTimeout(resolve, WAIT_MS));
  return Promise.race([loaded, timeout]);
}
