// One line to put a model of a meshstream server into another site's page
// (docs/BROWSER.md "Embed"):
//   <script src="https://models.example/web/embed.js" data-model="NAME" async></script>
// puts, where the tag stands, an <iframe> of the server's viewer page
// /view/NAME. Optional attributes: data-view (the hash of a shared view:
// "cam=...&tol=..."), data-width and data-height (CSS sizes, default 100%
// and 480px), data-title (the frame's accessible name). The viewer runs in
// the frame at the server's own origin: its token form, its worker, its
// requests, so the embedding page never sees the token or the model's bytes.
// The frame tells the page how the view goes with postMessage
// ({meshstream: {state, message, triangles, ...}}; docs/BROWSER.md).
(function () {
  'use strict';
  const script = document.currentScript;
  if (!script || !script.dataset.model)
    return;
  const page = new URL('../view/' + encodeURIComponent(script.dataset.model), script.src);
  if (script.dataset.view)
    page.hash = script.dataset.view;
  const frame = document.createElement('iframe');
  frame.src = page.href;
  frame.title = script.dataset.title || 'The 3D model ' + script.dataset.model;
  frame.allow = 'fullscreen';
  frame.style.border = '0';
  frame.style.width = script.dataset.width || '100%';
  frame.style.height = script.dataset.height || '480px';
  script.after(frame);
})();
