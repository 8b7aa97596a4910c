// The catalogue page (/): the models meshserve serves, from GET /catalog.json
// (the same as /catalog; its first 1000 by name; a static export's whole
// catalog.json, meshexport --web-dir), each with its thumbnail (/models/NAME/thumbnail,
// or the file a static export names,
// where the server has one) and its metadata, and a link to its viewer page
// (docs/BROWSER.md). Text from the catalogue (names, titles, creators,
// descriptions: a sidecar's, anyone's) only ever goes in as text nodes, never
// as markup.
'use strict';

function megabytes(bytes) {
  return (bytes / 1e6).toFixed(bytes < 1e7 ? 2 : 1) + ' MB';
}

// A <div class=NAME> holding text (as text).
function textDiv(className, text) {
  const div = document.createElement('div');
  div.className = className;
  div.textContent = text;
  return div;
}

async function showCatalogue() {
  const status = document.getElementById('status');
  const table = document.getElementById('models');
  window.meshstream = { state: 'loading', message: '' };
  try {
    // meshserve's paged catalogue, or a static export's whole one, which
    // ignores the query and names each model's page (view/NAME.html;
    // meshserve's are view/NAME). Paths are relative: a site may live in a
    // folder of its server.
    const answer = await fetch('catalog.json?limit=1000&sort=name');
    if (!answer.ok)
      throw new Error('the server answered ' + answer.status + ': ' + (await answer.text()).trim());
    const catalogue = await answer.json();
    const body = table.tBodies[0];
    let thumbnails = 0;
    const titles = [];
    for (const m of catalogue.models) {
      const row = body.insertRow();
      const picture = row.insertCell();
      picture.className = 'thumbnail';
      if (m.thumbnail) {
        const img = document.createElement('img');
        // a static export names its picture's file; meshserve serves it at models/NAME/thumbnail
        img.src = /^models\/[A-Za-z0-9_-]+\/thumbnail\.png$/.test(m.thumbnail) ? m.thumbnail
                                                                        : 'models/' + encodeURIComponent(m.name) + '/thumbnail';
        img.width = 160;
        img.height = 120;
        img.loading = 'lazy';
        img.alt = m.title || m.name;
        picture.appendChild(img);
        thumbnails++;
      }
      const about = row.insertCell();
      const link = document.createElement('a');
      link.href = /^view\/[A-Za-z0-9_-]+\.html$/.test(m.view || '') ? m.view
                                                                   : 'view/' + encodeURIComponent(m.name);
      link.textContent = m.title || m.name;
      about.appendChild(link);
      if (m.title) {
        about.appendChild(textDiv('name', m.name));
        titles.push(link.textContent);
      }
      const credit = [m.creator, m.date].filter(Boolean).join(', ');
      if (credit) about.appendChild(textDiv('credit', credit));
      if (m.licence) about.appendChild(textDiv('licence', m.licence));
      if (m.unit) about.appendChild(textDiv('unit', 'unit: ' + m.unit));
      if (m.description) about.appendChild(textDiv('description', m.description));
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
    window.meshstream = { state: 'complete', message: status.textContent, models: catalogue.models.length,
                          thumbnails: thumbnails, titles: titles,
                          scripts: document.getElementsByTagName('script').length };
  } catch (e) {
    status.textContent = 'Cannot read the catalogue: ' + e.message;
    status.className = 'error';
    window.meshstream = { state: 'error', message: status.textContent };
  }
}

showCatalogue();
