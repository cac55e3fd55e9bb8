// Drives emplan's dashboard in headless Chromium (Debian's /usr/bin/chromium through
// playwright-core) the way a field team would: select the mission, upload it with the token
// typed into the page's own dialog, start the flight with the page's button, watch the live leg
// table fill leg by leg, then open the flight's report. Saves screenshots; exits non-zero on any
// failure (a step timing out, a console error, a CSP violation, the token found in the page).
//
// With --pack NAME, the pack is typed into the upload form's Pack field before the flight, and
// after it the Packs page must list that pack with its one flight, a capacity measured, and its
// chart of capacity over cycles (screenshot packs.png).
//
// With --guard yes, instead: the guarded flight of MISSION (a service run with --guard rtl and a
// heavier --mock-vehicle): the live view's guard panel shows the warning and the return.
//
// node check.mjs --url URL --token-file FILE --mission NAME --out DIR [--broken NAME] [--infeasible NAME] [--pack NAME] [--guard yes] [--chromium PATH]
import { chromium } from 'playwright-core';
import { readFileSync, mkdirSync } from 'node:fs';
import { join } from 'node:path';

function args() {
  const out = { chromium: '/usr/bin/chromium', timeout: 180 };
  const argv = process.argv.slice(2);
  for (let k = 0; k < argv.length; k += 2) {
    const key = argv[k].replace(/^--/, '').replace(/-/g, '_');
    if (argv[k + 1] === undefined) throw new Error(`${argv[k]} needs a value`);
    out[key] = argv[k + 1];
  }
  for (const need of ['url', 'token_file', 'mission', 'out']) {
    if (!out[need]) throw new Error(`--${need.replace(/_/g, '-')} is required`);
  }
  return out;
}

const opts = args();
const token = readFileSync(opts.token_file, 'utf8').trim();
if (token.length < 16) throw new Error(`${opts.token_file}: no token in it`);
mkdirSync(opts.out, { recursive: true });
const timeout = Number(opts.timeout) * 1000;
const problems = [];
// Refusals this check provokes on purpose (a wrong token, an upload in flight): each expected once.
const provoked = [];
const log = (...a) => console.log('dashboard-check:', ...a);

async function noTokenInPage(page, when) {
  const html = await page.content();
  const stored = await page.evaluate(() => ({
    local: JSON.stringify(Object.assign({}, localStorage)),
    session: JSON.stringify(Object.assign({}, sessionStorage)),
    cookie: document.cookie,
    url: location.href,
  }));
  for (const [where, text] of [['the page', html], ['localStorage', stored.local], ['sessionStorage', stored.session], ['cookies', stored.cookie], ['the URL', stored.url]]) {
    if (text.includes(token)) throw new Error(`${when}: the token appears in ${where}`);
  }
}

async function imageLoaded(page, selector) {
  await page.waitForFunction(
    (sel) => {
      const img = document.querySelector(sel);
      return img && img.complete && img.naturalWidth > 0 && !img.closest('[hidden]');
    },
    selector,
    { timeout },
  );
}

// The energy guard on a guarded flight (`serve --guard rtl --mock-vehicle` a heavier vehicle):
// upload and start through the page, then the live view's guard panel shows the warning
// (below_reserve), the return (a `return` note, RETURNING) and keeps them to the flight's end.
async function guardedFlight(page) {
  await page.goto(opts.url + '/', { waitUntil: 'load' });
  const row = page.locator(`#missions-body tr[data-name="${opts.mission}"]`);
  await row.click();
  await page.waitForFunction(() => document.querySelector('#md-status-text')?.textContent === 'planned', null, { timeout });
  await page.click('#upload-btn');
  await page.locator('#token-dialog').waitFor({ state: 'visible' });
  await page.fill('#token-input', token);
  await page.click('#token-ok');
  await page.waitForFunction(() => document.querySelector('#upload-result')?.dataset.outcome, null, { timeout });
  const upload = await page.evaluate(() => document.querySelector('#upload-result').dataset.outcome);
  if (upload !== 'verified') throw new Error(`upload through the page: ${upload}`);
  await page.click('#tab-live');
  await page.click('#start-btn');
  await page.waitForFunction(() => document.querySelector('#start-result')?.dataset.outcome, null, { timeout });
  if ((await page.evaluate(() => document.querySelector('#start-result').dataset.outcome)) !== 'started') {
    throw new Error('start through the page: ' + (await page.evaluate(() => document.querySelector('#start-result').textContent)));
  }
  log(`guard: ${opts.mission} uploaded and started through the page`);
  // The panel appears with the guard's view once the flight is recorded.
  await page.locator('#guard').waitFor({ state: 'visible' });
  await page.waitForFunction(() => document.querySelectorAll('#gd-facts dt').length > 0, null, { timeout });
  // The warning: a note whose verdict is below_reserve, in the warning style.
  await page.waitForFunction(() => document.querySelector('#gd-notes li.warn[data-verdict="below_reserve"]'), null, { timeout });
  const warning = await page.evaluate(() => ({
    note: document.querySelector('#gd-notes li[data-verdict="below_reserve"]').textContent,
    verdict: document.querySelector('#gd-verdict').textContent,
  }));
  log(`guard: warning shown: ${warning.note} (panel: ${warning.verdict})`);
  await page.screenshot({ path: join(opts.out, 'guard-warning.png') });
  // The return: a `return` note and RETURNING on the panel.
  await page.waitForFunction(
    () => document.querySelector('#gd-notes li.warn[data-kind="return"]') && document.querySelector('#guard').dataset.returning === 'yes' && /^RETURNING/.test(document.querySelector('#gd-verdict').textContent),
    null,
    { timeout },
  );
  const facts = await page.evaluate(() => Object.fromEntries([...document.querySelectorAll('#gd-facts dt')].map((dt) => [dt.textContent, dt.nextElementSibling.textContent])));
  log(`guard: return shown: ${await page.locator('#gd-notes li[data-kind="return"]').textContent()}`);
  log(`guard: panel: ${JSON.stringify(facts)}`);
  for (const key of ['Left at landing', 'Reserve', 'Correction', 'Pack', 'Point of no return']) {
    if (!(key in facts)) throw new Error(`the guard panel has no ${key}`);
  }
  await page.screenshot({ path: join(opts.out, 'guard-return.png') });
  // To the flight's end: the notes stay, the panel still says the vehicle was sent home.
  await page.waitForFunction(() => document.querySelector('#live-note')?.dataset.ended, null, { timeout });
  const after = await page.evaluate(() => [document.querySelectorAll('#gd-notes li[data-kind="return"]').length, document.querySelector('#gd-verdict').textContent]);
  if (after[0] !== 1 || !/^RETURNING/.test(after[1])) throw new Error(`after the flight: ${JSON.stringify(after)}`);
  await noTokenInPage(page, 'after the guarded flight');
  await page.screenshot({ path: join(opts.out, 'guard-end.png') });
  log('guard: the flight ended with the return shown');
}

const browser = await chromium.launch({
  executablePath: opts.chromium,
  headless: true,
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'],
});
let failed = false;
let page = null;
try {
  const context = await browser.newContext({ viewport: { width: 1366, height: 768 } });
  page = await context.newPage();
  page.setDefaultTimeout(timeout);
  page.on('console', (m) => {
    // A refused request is also logged as "Failed to load resource": the response listener
    // below judges those, with their URL, against the refusals this check provokes.
    if (m.type() === 'error' && !m.text().startsWith('Failed to load resource: the server responded')) {
      problems.push(`console error: ${m.text()}`);
    }
  });
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  page.on('response', (r) => {
    if (r.status() < 400) return;
    const k = provoked.findIndex((p) => p.status === r.status() && r.url().endsWith(p.path));
    if (k >= 0) provoked.splice(k, 1);
    else problems.push(`HTTP ${r.status()} for ${r.url()}`);
  });
  page.on('requestfailed', (r) => {
    // An event stream closed when the page goes away is not a failure.
    if (!r.url().endsWith('/api/events')) problems.push(`request failed: ${r.url()} ${r.failure()?.errorText}`);
  });

  if (opts.guard) {
    await guardedFlight(page);
  } else {
    // The mission's plan: how many legs the energy order flies (the origin back included).
    // The service plans a file once it has settled (unchanged for its settle time): ask until
    // it is planned, or the timeout.
    let detail = {};
    for (const until = Date.now() + timeout; Date.now() < until; await new Promise((r) => setTimeout(r, 250))) {
      detail = await (await page.request.get(`${opts.url}/api/missions/${encodeURIComponent(opts.mission)}`)).json();
      if (detail.plan || detail.status === 'error') break;
    }
    const energy = (detail.plan?.orders || []).find((o) => o.objective === 'energy');
    if (!energy) throw new Error(`${opts.mission}: not planned by the service (${JSON.stringify(detail).slice(0, 300)})`);
    const legs = energy.legs.length;
    log(`${opts.mission}: ${legs} legs in the energy order`);

    // Missions: select the mission, its status, facts and figure.
    await page.goto(opts.url + '/', { waitUntil: 'load' });
    const row = page.locator(`#missions-body tr[data-name="${opts.mission}"]`);
    if (opts.broken) {
      // A mission file that does not read is listed with its located error.
      const cell = `#missions-body tr[data-name="${opts.broken}"] td.status`;
      await page.waitForFunction((sel) => document.querySelector(sel) && !['planning', 'changing'].includes(document.querySelector(sel).textContent), cell, { timeout });
      const status = await page.locator(cell).textContent();
      if (!/^error \((line|item) \d+\)$/.test(status)) throw new Error(`${opts.broken} is listed as ${JSON.stringify(status)}, not as an error with its line`);
      log(`${opts.broken}: listed as ${status}`);
    }
    if (opts.infeasible) {
      // A mission one battery cannot fly: listed infeasible, its sorties shown and offered.
      const cell = `#missions-body tr[data-name="${opts.infeasible}"] td.status`;
      await page.waitForFunction((sel) => /^infeasible/.test(document.querySelector(sel)?.textContent || ''), cell, { timeout });
      await page.click(`#missions-body tr[data-name="${opts.infeasible}"]`);
      await page.waitForFunction(() => /^infeasible/.test(document.querySelector('#md-status-text')?.textContent || ''), null, { timeout });
      await page.waitForFunction(() => document.querySelectorAll('#md-sorties tbody tr').length >= 2 && document.querySelectorAll('#upload-sortie option').length >= 3, null, { timeout });
      const shown = await page.evaluate(() => [document.querySelector('#md-status-text').textContent, document.querySelectorAll('#md-sorties tbody tr').length]);
      await imageLoaded(page, '#md-plot');
      await page.screenshot({ path: join(opts.out, 'missions-infeasible.png') });
      log(`${opts.infeasible}: ${shown[0]}, ${shown[1]} sorties shown`);
    }
    await row.click();
    await page.waitForFunction(() => document.querySelector('#md-status-text')?.textContent === 'planned', null, { timeout });
    await page.locator('#md-facts dt', { hasText: 'Battery' }).waitFor();
    await imageLoaded(page, '#md-plot');
    await noTokenInPage(page, 'on arrival');
    await page.screenshot({ path: join(opts.out, 'missions.png') });
    log('missions view: planned, facts and figure shown');

    // A wrong token typed: refused at the auth stage, shown, and forgotten by the page.
    provoked.push({ status: 401, path: `/api/missions/${encodeURIComponent(opts.mission)}/upload` });
    await page.click('#upload-btn');
    await page.locator('#token-dialog').waitFor({ state: 'visible' });
    await page.fill('#token-input', 'f'.repeat(token.length));
    await page.click('#token-ok');
    await page.waitForFunction(() => document.querySelector('#upload-result')?.dataset.outcome, null, { timeout });
    const refused = await page.evaluate(() => [document.querySelector('#upload-result').dataset.outcome, document.querySelector('#upload-result').textContent, document.querySelector('#token-state').textContent]);
    if (refused[0] !== 'failed' || !refused[1].includes('stage auth') || refused[2] !== 'Token: none') {
      throw new Error(`a wrong token: ${JSON.stringify(refused)}`);
    }
    log(`wrong token: ${refused[1]}`);
    await page.evaluate(() => delete document.querySelector('#upload-result').dataset.outcome);

    // Upload through the page, naming the pack flown: the button asks for the token.
    if (opts.pack) await page.fill('#upload-pack', opts.pack);
    await page.click('#upload-btn');
    await page.locator('#token-dialog').waitFor({ state: 'visible' });
    await page.fill('#token-input', token);
    await page.click('#token-ok');
    await page.waitForFunction(() => document.querySelector('#upload-result')?.dataset.outcome, null, { timeout });
    const upload = await page.evaluate(() => ({
      outcome: document.querySelector('#upload-result').dataset.outcome,
      text: document.querySelector('#upload-result').textContent,
    }));
    log(`upload: ${upload.outcome}: ${upload.text.replace(/\n/g, ' | ')}`);
    if (upload.outcome !== 'verified') throw new Error(`upload through the page: ${upload.text}`);
    if ((await page.inputValue('#token-input')) !== '') throw new Error('the token stayed in the dialog input');
    await noTokenInPage(page, 'after the upload');
    await page.screenshot({ path: join(opts.out, 'missions-uploaded.png') });

    // Start through the page (the token is held in memory: no dialog this time).
    await page.click('#tab-live');
    await page.click('#start-btn');
    await page.waitForFunction(() => document.querySelector('#start-result')?.dataset.outcome, null, { timeout });
    const start = await page.evaluate(() => document.querySelector('#start-result').textContent);
    if ((await page.evaluate(() => document.querySelector('#start-result').dataset.outcome)) !== 'started') {
      throw new Error(`start through the page: ${start}`);
    }
    log(`start: ${start}`);

    // An upload while the vehicle flies: refused, the failing stage shown.
    await page.waitForFunction(() => document.querySelector('#lv-armed')?.textContent === 'yes', null, { timeout });
    await page.click('#tab-missions');
    await page.evaluate(() => delete document.querySelector('#upload-result').dataset.outcome);
    provoked.push({ status: 409, path: `/api/missions/${encodeURIComponent(opts.mission)}/upload` });
    await page.click('#upload-btn');
    await page.waitForFunction(() => document.querySelector('#upload-result')?.dataset.outcome, null, { timeout });
    const inFlight = await page.evaluate(() => [document.querySelector('#upload-result').dataset.outcome, document.querySelector('#upload-result').textContent]);
    if (inFlight[0] !== 'failed' || !inFlight[1].includes('stage vehicle')) throw new Error(`an upload in flight: ${JSON.stringify(inFlight)}`);
    log(`upload in flight: ${inFlight[1]}`);
    await page.click('#tab-live');

    // The live table: legs appear one by one as the service's events arrive.
    const began = Date.now();
    let sawFlying = false;
    let sawPartial = false;
    let midShot = false;
    let seen = { done: 0, flying: 0, ended: null };
    while (Date.now() - began < timeout) {
      seen = await page.evaluate(() => ({
        done: document.querySelectorAll('#live-legs-body tr[data-state="done"]').length,
        flying: document.querySelectorAll('#live-legs-body tr[data-state="flying"]').length,
        ended: document.querySelector('#live-note')?.dataset.ended || null,
      }));
      if (!seen.ended) {
        sawFlying ||= seen.flying > 0;
        sawPartial ||= seen.done > 0 && seen.done < legs;
        if (!midShot && seen.done >= Math.ceil(legs / 2)) {
          await page.screenshot({ path: join(opts.out, 'live.png') });
          midShot = true;
        }
      }
      if (seen.ended && seen.done === legs) break;
      await page.waitForTimeout(100);
    }
    log(`live table: ${seen.done} of ${legs} legs done, flight ${seen.ended}; saw a leg in progress: ${sawFlying}, saw the table partly filled: ${sawPartial}`);
    if (!seen.ended) throw new Error(`the flight did not end within ${opts.timeout} s`);
    if (seen.done !== legs) throw new Error(`the live leg table shows ${seen.done} legs done, expected ${legs}`);
    if (!sawFlying || !sawPartial) throw new Error('the live leg table did not fill leg by leg during the flight');
    const liveRows = await page.locator('#live-legs-body tr').count();
    if (liveRows !== legs) throw new Error(`the live leg table has ${liveRows} rows, expected ${legs}`);
    const chartPoints = await page.evaluate(() => document.querySelector('#ch-power polyline')?.getAttribute('points')?.split(' ').length || 0);
    if (chartPoints < 10) throw new Error(`the power chart has ${chartPoints} points`);
    await page.screenshot({ path: join(opts.out, 'live-end.png') });
    if (!midShot) await page.screenshot({ path: join(opts.out, 'live.png') });

    // The report of the flight just flown.
    const flight = seen.ended;
    await page.click('#tab-flights');
    await page.waitForFunction((name) => document.querySelector('#rp-title')?.textContent === 'Flight ' + name, flight, { timeout });
    await page.waitForFunction((n) => document.querySelectorAll('#report-legs-body tr').length === n && !document.querySelector('#report-legs').hidden, legs, { timeout });
    await imageLoaded(page, '#rp-plot');
    const measured = await page.evaluate(() => [...document.querySelectorAll('#report-legs-body tr td:nth-child(4)')].map((td) => td.textContent));
    if (measured.some((m) => m === '-')) throw new Error(`a leg of the report is not measured: ${measured.join(', ')}`);
    for (const [id, type] of [['#rp-tlog', 'application/octet-stream'], ['#rp-csv', 'text/csv']]) {
      const href = await page.getAttribute(id, 'href');
      const answer = await page.request.get(opts.url + href);
      if (answer.status() !== 200 || !(answer.headers()['content-type'] || '').startsWith(type) || (await answer.body()).length === 0) {
        throw new Error(`${id} ${href}: HTTP ${answer.status()} ${answer.headers()['content-type']}`);
      }
    }
    const svg = await page.request.get(`${opts.url}/api/flights/${encodeURIComponent(flight)}/plot.svg`);
    if (!(svg.headers()['content-type'] || '').startsWith('image/svg+xml')) throw new Error('the flight figure is not SVG');
    await noTokenInPage(page, 'at the end');
    await page.screenshot({ path: join(opts.out, 'report.png') });
    await page.screenshot({ path: join(opts.out, 'report-full.png'), fullPage: true });
    log(`report: ${legs} legs, measured kJ ${measured.join(' ')}; .tlog and CSV links answer`);

    if (opts.pack) {
      // The Packs page: the pack flown, with its flight counted and a capacity measured. The
      // flight reaches the ledger once its files are complete: the page is opened again until
      // the pack is listed.
      const packRow = `#packs-body tr[data-name="${opts.pack}"]`;
      let listed = false;
      for (const until = Date.now() + timeout; !listed && Date.now() < until; ) {
        await page.click('#tab-flights');
        await page.click('#tab-packs');
        listed = await page
          .locator(packRow)
          .waitFor({ timeout: 2000 })
          .then(() => true)
          .catch(() => false);
      }
      if (!listed) throw new Error(`the Packs page does not list the pack ${opts.pack} flown`);
      const shown = await page.evaluate((sel) => {
        const row = document.querySelector(sel);
        const chart = document.querySelector(`#packs-charts figure[data-name="${row.dataset.name}"]`);
        return {
          flights: row.querySelector('td.flights').textContent,
          capacity: row.querySelector('td.capacity').textContent,
          cells: [...row.querySelectorAll('td')].map((td) => td.textContent),
          points: chart ? chart.querySelectorAll('circle.point').length : -1,
          ledger: document.querySelector('#packs-ledger').textContent,
        };
      }, packRow);
      log(`packs: ${opts.pack}: ${JSON.stringify(shown.cells)}; chart points ${shown.points}; ${shown.ledger}`);
      if (shown.flights !== '1') throw new Error(`the Packs page counts ${shown.flights} flights of ${opts.pack}, expected 1`);
      if (!/^\d+(\.\d+)?( ± \d+(\.\d+)?)?%$/.test(shown.capacity)) throw new Error(`the Packs page shows no capacity for ${opts.pack}: ${JSON.stringify(shown.capacity)}`);
      if (shown.points !== 1) throw new Error(`the chart of ${opts.pack} has ${shown.points} points, expected its one flight`);
      await noTokenInPage(page, 'on the Packs page');
      await page.screenshot({ path: join(opts.out, 'packs.png') });
    }
  }
  if (provoked.length) problems.push(`refusals expected and not seen: ${JSON.stringify(provoked)}`);
  if (problems.length) throw new Error(`the page reported problems:\n  ${problems.join('\n  ')}`);
  log(`ok: screenshots in ${opts.out}`);
} catch (e) {
  failed = true;
  console.error('dashboard-check: FAILED:', e.message);
  for (const p of problems) console.error('  ', p);
  if (page) await page.screenshot({ path: join(opts.out, 'failure.png'), fullPage: true }).catch(() => {});
} finally {
  await browser.close();
}
process.exit(failed ? 1 : 0);
