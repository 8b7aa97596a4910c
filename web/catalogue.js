// The catalogue page (/): the models meshserve serves, from GET /catalog.json
// (its first 1000 by name), each a link to its viewer page (docs/BROWSER.md).
'use strict';

function megabytes(bytes) {
  return (bytes / 1e6).toFixed(bytes < 1e7 ? 2 : 1) + ' MB';
}

async function showCatalogue() {
  const status = document.getElementById('status');
  const table = document.getElementById('models');
  window.meshstream = { state: 'loading', message: '' };
  try {
    // meshserve's paged catalogue, or a static export's whole one
    // (meshexport --web-dir), which ignores the query and names each
    // model's page (view/NAME.html; meshserve's are view/NAME)
    const answer = await fetch('catalog.json?limit=1000&sort=name');
    if (!answer.ok)
      throw new Error('the server answered ' + answer.status + ': ' + (await answer.text()).trim());
    const catalogue = await answer.json();
    const body = table.tBodies[0];
    for (const m of catalogue.models) {
      const row = body.insertRow();
      const link = document.createElement('a');
      link.href = /^view\/[A-Za-z0-9_-]+\.html$/.test(m.view || '') ? m.view
                                                                   : 'view/' + encodeURIComponent(m.name);
      link.textContent = m.name;
      row.insertCell().appendChild(link);
      const cells = [m.triangles.toLocaleString('en'), megabytes(m.archive_bytes),
                     m.public_max_bits < m.bits ? 'preview to ' + m.public_max_bits + ' bits'
                                                : 'public'];
      cells.forEach((text, k) => {
        const cell = row.insertCell();
        cell.textContent = text;
        if (k < 2) cell.className = 'number';
      });
    }
    table.hidden = false;
    const total = catalogue.total === undefined ? catalogue.models.length : catalogue.total;
    status.textContent = total + (total === 1 ? ' model' : ' models') +
      (catalogue.models.length < total ? ' (the first ' + catalogue.models.length + ' shown)' : '');
    window.meshstream = { state: 'complete', message: status.textContent, models: catalogue.models.length };
  } catch (e) {
    status.textContent = 'Cannot read the catalogue: ' + e.message;
    status.className = 'error';
    window.meshstream = { state: 'error', message: status.textContent };
  }
}

showCatalogue();
