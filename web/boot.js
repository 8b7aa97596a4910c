// The first script of the viewer page (view.html's head): it starts the
// decoding worker (worker.js) before anything else and tells it the model at
// once, so that the worker's scripts, its WebAssembly module's compilation
// and the fetches of the catalogue's entry and the index overlap the page's
// own loading and WebGL's start. view.js takes the worker and the model's
// name from here (window.meshstreamBoot) and sends the camera.
'use strict';
(() => {
  const tokenKey = 'meshstream-token';     // the tab's token (view.js's form keeps it)
  // /view/NAME from meshserve, or view/NAME.html in a static export
  const staticSite = location.pathname.endsWith('.html');
  const name = decodeURIComponent(location.pathname.replace(/^.*\/view\//, '').replace(/\.html$/, ''));
  // #threads=0 in the URL: decode on the worker's thread alone (a figure
  // for comparison; the worker otherwise takes the threaded module where
  // the page is cross-origin isolated)
  const single = new URLSearchParams(location.hash.slice(1)).get('threads') === '0';
  const worker = new Worker('../web/worker.js' + (single ? '?threads=0' : ''));
  worker.postMessage({ type: 'prefetch', name, token: sessionStorage.getItem(tokenKey) || '',
                       layout: staticSite ? 'static' : 'door' });
  window.meshstreamBoot = { worker, at: performance.now(), name, staticSite, tokenKey };
})();
