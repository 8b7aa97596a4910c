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
  // The decoder's WebAssembly, fetched and compiled from here while the
  // worker starts (a worker's start took 60 to 690 ms after this script ran
  // on the loaded test machine: docs/BROWSER.md), then handed to it; the
  // same module the worker would choose: the threaded one where the page is
  // cross-origin isolated. null where it cannot be (no compileStreaming, a
  // server that sends the module without application/wasm): the worker then
  // fetches it itself.
  const file = self.crossOriginIsolated === true && typeof SharedArrayBuffer === 'function' && !single
    ? 'meshstream-mt.wasm' : 'meshstream.wasm';
  const compiled = typeof WebAssembly === 'object' && WebAssembly.compileStreaming
    ? WebAssembly.compileStreaming(fetch('../web/' + file)).catch(() => null) : Promise.resolve(null);
  // where the first milliseconds went, from the navigation (the worker puts
  // them in window.meshstream.timing.boot): the page's answer, this script's
  // fetch and its start; and the page's clock's origin, against which the
  // worker places its own marks (timing.marksFromNavigation)
  const nav = performance.getEntriesByType('navigation')[0];
  const me = document.currentScript && performance.getEntriesByName(document.currentScript.src)[0];
  const ms = x => (typeof x === 'number' ? Math.round(x) : null);
  const bootTimes = { pageRequest: ms(nav && nav.requestStart), pageAnswer: ms(nav && nav.responseEnd),
                      bootFetched: ms(me && me.responseEnd), bootRan: ms(performance.now()),
                      timeOrigin: performance.timeOrigin };
  // The model's first three requests (its catalogue entry, its index's
  // head, its root cell: what the first look is drawn from), sent from here
  // too, before the worker's script has come (a round trip or two from a
  // distant server): the worker's own requests for them, the same URLs with
  // the same headers, are then answered by the browser's cache (the side
  // door lets it keep them; a request still on its way is joined, not sent
  // again). The paths are worker.js's LAYOUTS' (timing.warmAnswers counts
  // the answers the cache gave).
  const token = sessionStorage.getItem(tokenKey) || '';
  const model = 'models/' + encodeURIComponent(name);
  const firstPaths = staticSite ? ['catalog.json', model + '.head', model + '/cells/0/geometry']
    : ['catalog?limit=1000&q=' + encodeURIComponent(name), model + '/head', model + '/cells/0/geometry'];
  for (const path of firstPaths)
    fetch(new URL('../' + path, location.href).href,
          { headers: token ? { Authorization: 'Bearer ' + token } : {}, cache: 'default' })
      .then(r => r.arrayBuffer()).catch(() => null);   // the worker's own request tells what went wrong
  worker.postMessage({ type: 'prefetch', name, token, layout: staticSite ? 'static' : 'door', boot: bootTimes,
                       firstPaths });
  const handedOver = compiled.then(module => worker.postMessage({ type: 'module', file, module,
                                                                  at: Math.round(performance.now()) }));
  // view.js makes its WebGL context once the worker runs (its 'alive', the
  // first thing worker.js says) and has the module: creating a context holds
  // this thread for about 0.1 s on SwiftShader, and both the worker's start
  // and the module's hand-over wait for a turn of this thread (the worker
  // used to start only once the context was made; docs/BROWSER.md, "First
  // pixels"). Never more than READY_WAIT_MS after this script: a worker slow
  // to start does not hold the page's own start.
  // (window.meshstream.timing says which came first: `glAfter`, 'worker' or
  // 'wait', with `aliveMs` and `glMs`.)
  const READY_WAIT_MS = 400;
  const boot = { worker, at: performance.now(), name, staticSite, tokenKey, aliveAt: null, readyBy: null };
  const alive = new Promise(resolve => worker.addEventListener('message', function hello(e) {
    if (e.data && e.data.type === 'alive') {
      worker.removeEventListener('message', hello);
      boot.aliveAt = Math.round(performance.now());
      resolve();
    }
  }));
  boot.ready = Promise.race([
    Promise.all([alive, handedOver]).then(() => { boot.readyBy = boot.readyBy || 'worker'; }),
    new Promise(resolve => setTimeout(resolve, READY_WAIT_MS)).then(() => { boot.readyBy = boot.readyBy || 'wait'; })]);
  window.meshstreamBoot = boot;
})();
