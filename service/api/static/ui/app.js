// metairl dashboard: plain JavaScript against the /v1 API (docs/api.md, "The dashboard").
//
// The API key lives in this tab's sessionStorage and goes out as `Authorization: Bearer`. Live progress
// comes from `GET /v1/jobs/{id}/events` as Server-Sent Events when the server streams them (read with
// fetch, since EventSource cannot send the header); when it answers anything else, the page polls
// `GET /v1/jobs/{id}` instead.
"use strict";

const KEY_STORAGE = "metairl.apiKey";
const TERMINAL = new Set(["succeeded", "failed", "cancelled"]);
const POLL_MS = 1000;
const JOB_LIST_MS = 10000;
const STREAM_RETRIES = 3;
// Browsers open at most 6 HTTP/1.1 connections to one server; streams beyond these few would starve the
// page's other requests, so further jobs are polled.
const MAX_STREAMS = 3;
// The API's root: the page is served at <root>/ui.
const ROOT = location.pathname.replace(/\/ui\/?$/, "");

const state = {
  key: sessionStorage.getItem(KEY_STORAGE) || "",
  demonstrators: new Map(), // id -> demonstrator
  jobs: new Map(), // id -> job
  rows: new Map(), // id -> {tr, errorTr}
  watching: new Map(), // id -> AbortController
  selected: null, // job id whose results are shown
  motion: null, // demonstrator id whose motion readout is shown
  blobUrls: { results: [], comparison: [], sway: [] }, // object URLs of the pictures shown, by the view that shows them
  sway: null, // demonstrator id whose quiet-standing panel is shown
  swayCall: 0, // bumped by each trial shown, so an earlier trial's late answers never redraw the sway panel
  swayView: 0, // bumped by each showSway (and hideSway), the same for the panel's comparison of conditions
  listTimer: null,
  generation: 0, // bumped when the key changes, so late answers for the old key are dropped
  jobsRequests: 0, // job-list requests made: only the answer to the latest is drawn
  resultsCall: 0, // bumped by each showResults, so an earlier call's late answers never redraw the results
  motionCall: 0, // the same for showMotion
  comparisonCall: 0, // the same for showComparison
  comparisonAbort: null, // aborts the requests of the comparison shown, once another replaces it
  webhooksCall: 0, // the same for loadWebhooks: an earlier listing never redraws over a later one
  mode: "", // how progress arrives: "stream" or "polling"
  openStreams: 0,
  cursors: [null], // the job list's page cursors: [first page, second page, …] up to the page shown
  nextCursor: null, // the cursor of the page after the one shown (null: it is the last)
  run: null, // job id whose run page is shown
  history: null, // {jobId, attempt, maxSteps, bestStep, source, points} of the run page's loss curve
  runCall: 0, // bumped by each showRun, so an earlier call's late answers never redraw the run page
  configSchema: null, // JobConfig's properties from /openapi.json (defaults, ranges, descriptions)
  mdps: [],
  lightboxCall: 0, // bumped by each channel drawn or lightbox closed, so a late reward never draws over it
  lightboxOpener: null, // the element focused when the lightbox opened: focus returns to it on closing
};

class ApiError extends Error {
  constructor(status, detail) {
    super(detail);
    this.status = status;
  }
}

const $ = (id) => document.getElementById(id);

// A DOM element; children are nodes or strings (set as text, never parsed as HTML).
function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [name, value] of Object.entries(attrs)) {
    if (value === undefined || value === null || value === false) continue;
    if (name === "class") node.className = value;
    else if (name === "style") Object.assign(node.style, value); // CSSOM, allowed by the page's CSP
    else if (name.startsWith("on")) node.addEventListener(name.slice(2), value);
    else node.setAttribute(name, value === true ? "" : String(value));
  }
  node.append(...nodes(children));
  return node;
}

// Children as `el` takes them (nodes, strings, lists of them) as nodes; null, undefined and false are left out,
// where the DOM's own append and replaceChildren would print them as "null" or "undefined".
function nodes(children) {
  return children
    .flat(Infinity)
    .filter((child) => child !== undefined && child !== null && child !== false)
    .map((child) => (child instanceof Node ? child : document.createTextNode(String(child))));
}

// Replace a node's children with these (as `el` takes them).
function fill(node, ...children) {
  node.replaceChildren(...nodes(children));
  return node;
}

function fmt(x, digits = 3) {
  if (x === null || x === undefined || Number.isNaN(x)) return "–";
  const a = Math.abs(x);
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) return x.toExponential(2);
  return fixed(x, digits);
}

// Always `digits` decimals, and a value that rounds to zero without a sign ("0.00", never "-0.00").
function fixed(x, digits = 3) {
  if (x === null || x === undefined || Number.isNaN(x)) return "–";
  const text = x.toFixed(digits);
  return /^-0\.?0*$/.test(text) ? text.slice(1) : text;
}

// One format for every value of a column, from the largest of them: fixed decimals enough for its two
// leading digits (3 at least, 6 at most; 3 for a column of rounding noise), exponents only for a column of
// large values; "–" for a missing one.
function columnFormat(values) {
  const finite = values.filter((v) => typeof v === "number" && Number.isFinite(v)).map(Math.abs);
  const top = finite.length ? Math.max(...finite) : 0;
  if (top >= 1e5) return (x) => (typeof x === "number" && Number.isFinite(x) ? x.toExponential(2) : "–");
  const digits = top >= 1e-6 ? Math.min(6, Math.max(3, 1 - Math.floor(Math.log10(top)))) : 3;
  return (x) => fixed(x, digits);
}

function showMessage(text, kind = "error") {
  const box = $("message");
  box.textContent = text;
  box.className = `message ${kind === "info" ? "info" : ""}`;
  box.hidden = !text;
}

// ---- HTTP ----------------------------------------------------------------------------------------

async function api(path, options = {}) {
  const headers = { Authorization: `Bearer ${state.key}`, ...(options.headers || {}) };
  const response = await fetch(ROOT + path, { ...options, headers });
  if (!response.ok) {
    let detail = response.statusText;
    try {
      const problem = await response.json();
      detail = problem.detail || problem.title || detail;
    } catch (_) {
      /* not problem+json */
    }
    throw new ApiError(response.status, detail);
  }
  return response;
}

async function getJson(path, options) {
  return (await api(path, options)).json();
}

// Every item of a paged list, following next_cursor (at most 20 pages of 100).
async function getAll(path) {
  const items = [];
  let cursor = null;
  for (let page = 0; page < 20; page++) {
    const query = new URLSearchParams({ limit: "100" });
    if (cursor) query.set("cursor", cursor);
    const body = await getJson(`${path}?${query}`);
    items.push(...body.data);
    if (!body.has_more) break;
    cursor = body.next_cursor;
  }
  return items;
}

function reportError(error) {
  if (error && error.name === "AbortError") return;
  if (error instanceof ApiError && error.status === 401) {
    showMessage("The server refused this API key (401). Paste a valid key of your lab.");
    stopAll();
    $("main").hidden = true;
    $("welcome").hidden = false;
    return;
  }
  showMessage(error instanceof ApiError ? `${error.status}: ${error.message}` : String(error));
}

// ---- key -----------------------------------------------------------------------------------------

function useKey(key) {
  state.key = key.trim();
  stopAll();
  if (!state.key) return;
  sessionStorage.setItem(KEY_STORAGE, state.key);
  $("key-input").value = state.key;
  $("welcome").hidden = true;
  $("main").hidden = false;
  $("refresh").disabled = false;
  showMessage("");
  loadEverything();
}

function forgetKey() {
  sessionStorage.removeItem(KEY_STORAGE);
  state.key = "";
  $("key-input").value = "";
  stopAll();
  $("main").hidden = true;
  $("welcome").hidden = false;
  $("refresh").disabled = true;
  showMessage("The key was removed from this tab.", "info");
}

// Stop following the lab's jobs and clear everything shown of it, so that nothing of one lab stays on
// screen (or is redrawn by a late answer) once another key is in use.
function stopAll() {
  state.generation += 1;
  state.webhooksCall += 1;
  for (const controller of state.watching.values()) controller.abort();
  state.watching.clear();
  clearInterval(state.listTimer);
  state.listTimer = null;
  state.jobs.clear();
  state.rows.clear();
  state.demonstrators.clear();
  state.mdps = [];
  state.cursors = [null];
  state.nextCursor = null;
  hideRun();
  hideResults();
  hideMotion();
  hideSway();
  closeLightbox();
  fill($("jobs"));
  fill($("demonstrators"), loading());
  fill($("mdps"), loading());
  fill($("filter-demonstrator"), el("option", { value: "" }, "any"));
  fill($("submit-demonstrator"));
  fill($("submit-tasks"), el("legend", {}, "Tasks"));
  fill($("webhooks"));
  hideSecret();
  $("webhook-error").hidden = true;
  submitError("");
  releaseBlobs();
}

// The run page hidden and emptied; its late answers dropped.
function hideRun() {
  state.runCall += 1;
  state.run = null;
  state.history = null;
  const section = $("run");
  section.hidden = true;
  delete section.dataset.job;
  $("run-title").textContent = "Run";
  for (const id of ["run-status", "run-facts", "run-config", "loss-curve", "downloads"]) fill($(id));
}

// The results hidden and emptied; their late answers dropped.
function hideResults() {
  state.resultsCall += 1;
  state.selected = null;
  const section = $("results");
  section.hidden = true;
  delete section.dataset.job;
  $("results-title").textContent = "Results";
  for (const id of ["heatmaps", "matrix", "key-states"]) fill($(id));
  releaseBlobs("results");
}

// The motion readout hidden and emptied; its late answers (the comparison's too) dropped.
function hideMotion() {
  state.motionCall += 1;
  state.comparisonCall += 1;
  state.comparisonAbort?.abort();
  state.comparisonAbort = null;
  state.motion = null;
  const section = $("motion");
  section.hidden = true;
  delete section.dataset.demonstrator;
  $("motion-title").textContent = "Motion readout";
  $("motion-meta").textContent = "";
  $("compare-label").textContent = "a, against b =";
  for (const id of ["kinematics", "learned", "comparison", "compare-with"]) fill($(id));
  for (const node of document.querySelectorAll("#demonstrators .dem.selected")) node.classList.remove("selected");
  releaseBlobs("comparison");
}

// The quiet-standing panel hidden and emptied; its late answers dropped.
function hideSway() {
  state.swayCall += 1;
  state.swayView += 1;
  state.sway = null;
  const section = $("sway");
  section.hidden = true;
  delete section.dataset.demonstrator;
  $("sway-title").textContent = "Quiet standing";
  $("sway-meta").textContent = "";
  for (const id of ["sway-recording", "sway-measures", "sway-picture", "sway-groups"]) fill($(id));
  releaseBlobs("sway");
}

// After the lab's data changed (a refresh, a delete): the motion and sway panels drawn again from what is
// there now, or hidden where their demonstrator, or its recordings of that kind, are gone.
function redrawPanels() {
  const motion = state.demonstrators.get(state.motion);
  if (state.motion !== null && motion && hasMovements(motion)) showMotion(motion.id);
  else if (state.motion !== null) hideMotion();
  const sway = state.demonstrators.get(state.sway);
  if (state.sway !== null && sway && standingTrials(sway).length) showSway(sway.id, { trial: $("sway-recording").value });
  else if (state.sway !== null) hideSway();
}

async function loadEverything() {
  const generation = state.generation;
  try {
    await Promise.all([loadDemonstrators(generation), loadConfigSchema()]);
    renderSubmitForm(); // its settings need the schema
    await Promise.all([loadJobs(generation), loadWebhooks(generation), loadMdps(generation)]);
  } catch (error) {
    if (generation === state.generation) reportError(error);
    return;
  }
  clearInterval(state.listTimer);
  state.listTimer = setInterval(() => {
    loadJobs(state.generation).catch(reportError);
    loadWebhooks(state.generation).catch(reportError);
  }, JOB_LIST_MS);
}

// ---- demonstrators -------------------------------------------------------------------------------

async function loadDemonstrators(generation) {
  const demonstrators = await getAll("/v1/demonstrators");
  const details = await Promise.all(
    demonstrators.map(async (d) => {
      const [tasks, recordings] = await Promise.all([
        getAll(`/v1/demonstrators/${encodeURIComponent(d.id)}/tasks`),
        getAll(`/v1/demonstrators/${encodeURIComponent(d.id)}/recordings`).catch(() => []),
      ]);
      // In the order they were made (the API lists newest first): a motion session's directions as recorded,
      // and a job submitted from the form in the order a job submitted over the API has.
      tasks.sort((a, b) => (a.created_at < b.created_at ? -1 : a.created_at > b.created_at ? 1 : 0));
      return { ...d, tasks, recordings };
    }),
  );
  if (generation !== state.generation) return;
  state.demonstrators = new Map(details.map((d) => [d.id, d]));
  renderDemonstrators();
  renderDemonstratorFilter();
  renderSubmitForm();
}

function renderDemonstrators() {
  const box = $("demonstrators");
  if (state.demonstrators.size === 0) {
    fill(box, el("p", { class: "empty" }, "No demonstrators yet."));
    return;
  }
  fill(box,
    ...[...state.demonstrators.values()].map((d) =>
      el(
        "div",
        { class: `dem${state.motion === d.id ? " selected" : ""}`, "data-demonstrator": d.id },
        el("div", { class: "dem-name" }, d.name),
        el("div", { class: "id" }, d.id),
        demonstratorActions(d), // above the task list, which may scroll in its box
        d.tasks.length
          ? el(
              "ul",
              { class: "tasks" },
              d.tasks.map((t) =>
                el(
                  "li",
                  { "data-task": t.id },
                  t.name,
                  " ",
                  el("span", { class: "meta" }, `· ${t.n_trajectories} traj., ${t.n_steps} steps${t.has_true_reward ? " · true reward" : ""}`),
                  " ",
                  deleteButton("task", t.id, `task ${t.name} with its demonstrations and the jobs that fitted it`),
                ),
              ),
            )
          : el("div", { class: "sub" }, "no tasks"),
        d.recordings.length
          ? el(
              "div",
              { class: "sub" },
              "Recordings: ",
              d.recordings
                .map((r) => `${recordingName(r)} (${r.protocol === "standing" ? "standing, " : ""}${r.n_samples} samples, ${fmt(r.duration, 1)} s)`)
                .join("; "),
            )
          : el("div", { class: "sub" }, "no recordings"),
      ),
    ),
  );
}

// A demonstrator's buttons in the order of the work: read out what was recorded, fit a job to its tasks, and
// last, apart, delete it. They come under its name, before its tasks.
function demonstratorActions(d) {
  return el(
    "div",
    { class: "dem-actions" },
    // The motion readout reads movements only: a demonstrator with standing trials alone has none.
    hasMovements(d)
      ? el("button", { class: "small quiet", "data-action": "motion", onclick: () => showMotion(d.id, { scroll: true }) }, "Motion readout")
      : null,
    swayButton(d),
    d.tasks.length
      ? el("button", { class: "small quiet", "data-action": "new-job", title: `Fit a job to the tasks of ${d.name}`, onclick: () => newJobFor(d.id) }, "New job")
      : null,
    deleteButton("demonstrator", d.id, `demonstrator ${d.name} with its tasks, recordings and jobs`),
  );
}

// The job form with the demonstrator picked (every task ticked), scrolled to.
function newJobFor(id) {
  const select = $("submit-demonstrator");
  select.value = id;
  renderSubmitTasks();
  select.closest("section").scrollIntoView({ block: "start" });
  select.focus();
}

function demonstratorName(id) {
  const d = state.demonstrators.get(id);
  return d ? d.name : id;
}

// A recording as the page names it: its name, else (an upload without one) its id.
function recordingName(r) {
  return r.name || r.id;
}

// Whether a recording holds instructed movements (cut into demonstrations, read out per direction), not a
// quiet-standing trial: the recordings listing's `protocol`.
function isMovement(r) {
  return r.protocol === "movements";
}

function hasMovements(d) {
  return d.recordings.some(isMovement);
}

function standingTrials(d) {
  return d.recordings.filter((r) => r.protocol === "standing");
}

// ---- jobs ----------------------------------------------------------------------------------------

async function loadJobs(generation) {
  const ticket = ++state.jobsRequests;
  const { jobs, nextCursor } = await jobsPage();
  // Only the latest request draws: a slower answer for a page or filter left since must not overwrite it.
  if (generation !== state.generation || ticket !== state.jobsRequests) return;
  state.nextCursor = nextCursor;
  renderPager();
  dropRowsNotIn(new Set(jobs.map((j) => j.id)));
  const unknown = jobs.some((j) => !state.demonstrators.has(j.demonstrator_id));
  if (unknown) await loadDemonstrators(generation).catch(() => undefined);
  for (const job of jobs) {
    const known = state.jobs.get(job.id);
    // A watched job's row is kept current by its stream or poll; the list only adds new ones.
    if (!known || !state.watching.has(job.id)) updateJob(job);
  }
  orderRows(jobs.map((j) => j.id));
  $("jobs-empty").hidden = jobs.length > 0;
  for (const job of jobs) watch(job);
}

function orderRows(ids) {
  const body = $("jobs");
  for (const id of ids) {
    const row = state.rows.get(id);
    if (row) body.append(row.tr, row.errorTr);
  }
}

function updateJob(job) {
  const previous = state.jobs.get(job.id);
  state.jobs.set(job.id, job);
  renderJobRow(job);
  if (state.run === job.id) renderRun(job, previous);
  if (previous && previous.status !== "succeeded" && job.status === "succeeded" && state.selected === null) {
    showResults(job.id);
  }
}

function renderJobRow(job) {
  let row = state.rows.get(job.id);
  if (!row) {
    const tr = el("tr", { "data-job": job.id });
    const errorTr = el("tr", { class: "error-row", hidden: true }, el("td", { class: "error", colspan: 8 }));
    row = { tr, errorTr };
    state.rows.set(job.id, row);
    $("jobs").prepend(tr, errorTr);
    $("jobs-empty").hidden = true;
  }
  const p = job.progress;
  const steps = p ? p.max_steps || job.config.max_steps : job.config && job.config.max_steps;
  const fraction = job.status === "succeeded" ? 1 : p && steps ? Math.min(1, p.step / steps) : 0;
  const done = job.status === "succeeded";
  // The fit's own time (the engine's clock at this step), apart from the attempt's time from start to end.
  const barText = p ? `step ${p.step} / ${steps}${p.elapsed_s != null ? ` · fitting ${fmt(p.elapsed_s, 1)} s` : ""}` : job.status === "queued" ? "waiting for a worker" : "";
  const created = new Date(job.created_at);
  row.tr.dataset.status = job.status;
  row.tr.className = state.selected === job.id || state.run === job.id ? "selected" : "";
  fill(row.tr,
    el("td", {}, el("button", { class: "link id", title: "Open the run page", "data-action": "run", onclick: () => showRun(job.id, { scroll: true }) }, job.id), el("div", { class: "bar-text" }, created.toLocaleString())),
    el("td", {}, demonstratorName(job.demonstrator_id), el("div", { class: "bar-text" }, `${job.task_ids.length} tasks`)),
    el("td", {}, el("span", { class: `badge ${job.status}`, "data-role": "status" }, job.cancel_requested && !TERMINAL.has(job.status) ? `${job.status} (cancelling)` : job.status)),
    el(
      "td",
      {},
      el("div", { class: `bar${done ? " done" : ""}`, role: "progressbar", "aria-valuemin": 0, "aria-valuemax": 100, "aria-valuenow": Math.round(fraction * 100) }, el("span", { style: { width: `${(fraction * 100).toFixed(1)}%` } })),
      el("div", { class: "bar-text", title: "The step the fit has reached, and the fit's own time to it" }, barText),
    ),
    el("td", { class: "num" }, p ? fmt(p.loss) : "–"),
    el("td", { class: "config-cell", "data-role": "config" }, configSummary(job.config)),
    el("td", { class: "num", "data-role": "best-step" }, job.best_step ?? "–", el("div", { class: "bar-text", title: "The last attempt, and its time from start to end: the fit, loading the data and storing the rewards" }, attemptsText(job))),
    el(
      "td",
      { class: "actions" },
      !TERMINAL.has(job.status)
        ? el("button", { class: "danger small", "data-action": "cancel", disabled: job.cancel_requested, onclick: () => cancelJob(job.id) }, "Cancel")
        : null,
      job.status === "succeeded"
        ? el("button", { class: "small", "data-action": "results", onclick: () => showResults(job.id) }, "Results")
        : null,
      TERMINAL.has(job.status) ? deleteButton("job", job.id, `job ${job.id} with its events and learned rewards`) : null,
    ),
  );
  const errorCell = row.errorTr.firstChild;
  errorCell.textContent = job.error || "";
  row.errorTr.hidden = !job.error;
}

async function cancelJob(id) {
  try {
    const job = await getJson(`/v1/jobs/${encodeURIComponent(id)}/cancel`, { method: "POST" });
    updateJob(job);
  } catch (error) {
    reportError(error);
  }
}

// ---- live progress: the event stream, else polling -----------------------------------------------

function setMode(mode) {
  if (state.mode === mode) return;
  state.mode = mode;
  const labels = { stream: "● live (event stream)", polling: `● live (polling every ${POLL_MS / 1000} s)`, "": "" };
  $("live").textContent = labels[mode];
}

function watch(job) {
  if (TERMINAL.has(job.status) || state.watching.has(job.id)) return;
  const controller = new AbortController();
  state.watching.set(job.id, controller);
  const generation = state.generation;
  follow(job.id, controller.signal)
    .catch((error) => {
      if (generation === state.generation) reportError(error);
    })
    .finally(() => {
      if (state.watching.get(job.id) === controller) state.watching.delete(job.id);
      if (state.watching.size === 0) setMode("");
    });
}

async function follow(id, signal) {
  let lastEventId = null;
  for (let attempt = 0; attempt < STREAM_RETRIES && state.openStreams < MAX_STREAMS; attempt++) {
    const outcome = await stream(id, signal, lastEventId).catch((error) => {
      if (error.name === "AbortError") throw error;
      if (error instanceof ApiError && error.status === 401) throw error;
      return { ended: false, unsupported: false, lastEventId };
    });
    if (outcome.ended) return;
    if (outcome.unsupported) break;
    lastEventId = outcome.lastEventId;
  }
  await poll(id, signal);
}

// Read the SSE stream of one job. Resolves {ended} once a terminal status arrived (or the job is final),
// {unsupported} when the server answered something other than an event stream.
async function stream(id, signal, lastEventId) {
  const headers = { Accept: "text/event-stream" };
  if (lastEventId) headers["Last-Event-ID"] = lastEventId;
  const response = await api(`/v1/jobs/${encodeURIComponent(id)}/events`, { headers, signal });
  const type = response.headers.get("content-type") || "";
  if (!type.startsWith("text/event-stream") || !response.body) {
    await response.body?.cancel().catch(() => undefined);
    return { ended: false, unsupported: true, lastEventId };
  }
  setMode("stream");
  const reader = response.body.pipeThrough(new TextDecoderStream()).getReader();
  let buffer = "";
  state.openStreams += 1;
  try {
    for (;;) {
      const { value, done } = await reader.read();
      if (done) break;
      buffer += value;
      const blocks = buffer.split(/\r\n\r\n|\n\n|\r\r/);
      buffer = blocks.pop();
      for (const block of blocks) {
        const event = parseEvent(block);
        if (!event) continue;
        if (event.id !== null) lastEventId = event.id;
        if (await onEvent(id, event)) return { ended: true, unsupported: false, lastEventId };
      }
    }
  } finally {
    state.openStreams -= 1;
    reader.cancel().catch(() => undefined);
  }
  // The stream closed: it ends after the terminal status, so look at the job itself.
  const job = await refreshJob(id);
  return { ended: TERMINAL.has(job.status), unsupported: false, lastEventId };
}

function parseEvent(block) {
  let name = "message";
  let id = null;
  const data = [];
  for (const line of block.split(/\r\n|\n|\r/)) {
    if (!line || line.startsWith(":")) continue;
    const colon = line.indexOf(":");
    const field = colon < 0 ? line : line.slice(0, colon);
    let value = colon < 0 ? "" : line.slice(colon + 1);
    if (value.startsWith(" ")) value = value.slice(1);
    if (field === "event") name = value;
    else if (field === "data") data.push(value);
    else if (field === "id") id = value;
  }
  if (data.length === 0) return null;
  let payload;
  try {
    payload = JSON.parse(data.join("\n"));
  } catch (_) {
    return null;
  }
  return { name, id, data: payload };
}

// Apply one event to the job's row; true once the job is final.
async function onEvent(id, event) {
  const job = state.jobs.get(id);
  if (!job) return false;
  const data = event.data || {};
  if (event.name === "progress" || data.kind === "progress") {
    const progress = data.progress || data;
    if (typeof progress.step === "number") {
      if (state.run === id) extendHistory(id, progress, data.attempt);
      const status = job.status === "queued" ? "running" : job.status;
      updateJob({ ...job, status, progress: { ...(job.progress || {}), ...progress } });
    }
    return false;
  }
  if (event.name === "status" || data.kind === "status") {
    // The job row has the rest (error, attempts, timestamps): read it.
    const fresh = await refreshJob(id);
    return TERMINAL.has(fresh.status);
  }
  return false;
}

async function refreshJob(id) {
  const job = await getJson(`/v1/jobs/${encodeURIComponent(id)}`);
  if (state.rows.has(id)) updateJob(job); // a job whose row the list dropped meanwhile stays off the page
  return job;
}

// Whether a job is still there (false for none, or once deleted, on this page or elsewhere).
async function jobExists(id) {
  if (id === null) return false;
  try {
    await getJson(`/v1/jobs/${encodeURIComponent(id)}`);
    return true;
  } catch (error) {
    if (error instanceof ApiError && error.status === 404) return false;
    throw error;
  }
}

async function poll(id, signal) {
  setMode("polling");
  while (!signal.aborted) {
    const job = await getJson(`/v1/jobs/${encodeURIComponent(id)}`, { signal });
    if (signal.aborted) return;
    updateJob(job);
    if (TERMINAL.has(job.status)) return;
    await new Promise((resolve) => setTimeout(resolve, POLL_MS));
  }
}

// ---- results -------------------------------------------------------------------------------------

// Revoke the object URLs of one view's pictures ("results" or "comparison"), or of every view.
function releaseBlobs(view) {
  for (const name of view ? [view] : Object.keys(state.blobUrls)) {
    for (const url of state.blobUrls[name]) URL.revokeObjectURL(url);
    state.blobUrls[name] = [];
  }
}

async function showResults(id, { scroll = false } = {}) {
  const call = ++state.resultsCall;
  const current = () => call === state.resultsCall;
  state.selected = id;
  for (const [jobId, row] of state.rows) row.tr.className = jobId === id ? "selected" : "";
  releaseBlobs("results");
  const section = $("results");
  section.hidden = false;
  section.dataset.job = id;
  $("results-title").textContent = `Results of ${id}`;
  if (scroll) section.scrollIntoView({ block: "start" });
  fill($("heatmaps"), loading());
  fill($("matrix"), loading());
  fill($("key-states"), loading());
  // The matrix (slow on a large MDP) comes on its own: the heatmaps are drawn as soon as the rewards come.
  showMatrix(id, current);
  try {
    const rewards = await getJson(`/v1/jobs/${encodeURIComponent(id)}/rewards`);
    if (!current()) return;
    renderHeatmaps(rewards, current, state.jobs.get(id));
    // Side by side while the matrix is small; stacked (each full width, scrolling inside) once it is not.
    document.querySelector(".results-grid").classList.toggle("stacked", rewards.tasks.length + 1 > 6);
    const keyStates = await Promise.all(
      rewards.tasks.map((t) => getJson(`/v1/rewards/${encodeURIComponent(t.reward_id)}/key-states?top=5`)),
    );
    if (!current()) return;
    renderKeyStates(rewards.tasks, keyStates, state.jobs.get(id));
  } catch (error) {
    if (!current()) return;
    for (const box of [$("heatmaps"), $("key-states")]) if (box.querySelector("[data-role='loading']")) fill(box, unavailable(error));
    reportError(error);
  }
}

// The job's comparison matrix into its box, with its own loading and error state.
async function showMatrix(id, current) {
  try {
    const matrix = await getJson(`/v1/jobs/${encodeURIComponent(id)}/comparison-matrix`);
    if (current()) renderMatrix(matrix);
  } catch (error) {
    if (!current()) return;
    fill($("matrix"), unavailable(error));
    if (error instanceof ApiError && error.status === 401) reportError(error);
  }
}

// Per-state quantities drawn beside each reward when its links name them, with how to read each.
const BESIDE_REWARD = [
  ["uncertainty", "spread across the ensemble's members: how far a refit moves it (not its error)"],
  ["evidence", "evidence: on a demonstrated path (yellow), one move off (teal), elsewhere (purple)"],
];

function renderHeatmaps(rewards, current, job) {
  const layout = rewards.tasks.length ? layoutOfTask(rewards.tasks[0].task_id) : null;
  const cards = [rewards.baseline, ...rewards.tasks].map((reward) => {
    const title = reward.kind === "baseline" ? "baseline (shared)" : reward.task_name || reward.task_id;
    const s = reward.summary;
    const picture = reward.links.png
      ? el("img", { alt: `heatmap of ${title}`, "data-reward": reward.reward_id })
      : el("div", { class: "nopic" }, "No layout on this MDP, so no heatmap (download JSON or CSV).");
    // Beside the reward, what it rests on: how far its ensemble's members disagree, and where demonstrations pass.
    const beside = BESIDE_REWARD.filter(([quantity]) => reward.links[`${quantity}_png`]).map(([quantity, caption]) =>
      el(
        "div",
        { class: "beside", "data-role": quantity },
        el("img", { alt: `${quantity} of ${title}` }),
        el("span", { class: "stats" }, caption),
      ),
    );
    const card = el(
      "figure",
      { class: `heatmap ${reward.kind}`, "data-reward-kind": reward.kind },
      el("h4", {}, title),
      picture,
      el(
        "figcaption",
        { class: "stats" },
        `min ${fmt(s.min)} · max ${fmt(s.max)} (state ${s.argmax_state})`,
        reward.truth_pearson !== null ? ` · r vs truth ${fmt(reward.truth_pearson, 2)}` : "",
      ),
      // How to read this reward, where the API says it needs saying (a velocity-grid baseline, sharing none).
      reward.note ? el("details", { class: "note", "data-role": "note" }, el("summary", {}, "How to read this baseline"), reward.note) : null,
      beside.length ? el("div", { class: "beside-row" }, ...beside) : null,
    );
    if (reward.links.png) {
      zoomable(picture, `heatmap of ${title}`, () => openLightbox(picture.src, title, layout && layout.channels > 1 ? { reward, layout } : null));
      loadImage(picture, "results", current, reward.links.png);
    }
    for (const box of beside) {
      const img = box.querySelector("img");
      const what = `${box.dataset.role} of ${title}`;
      zoomable(img, what, () => openLightbox(img.src, what, null, what));
      loadImage(img, "results", current, reward.links[`${box.dataset.role}_png`]);
    }
    return card;
  });
  // A layout of many channels (a velocity grid's eight directions) is one wide picture of small panels:
  // its cards take a wider column, fewer a row, so each panel stays legible.
  $("heatmaps").classList.toggle("wide", Boolean(layout && layout.channels > 3));
  // λ 0: every task reward is the baseline, so the cards below are one picture; said once, above them.
  const same =
    job && job.shrinkage === 0 && rewards.tasks.length
      ? el("p", { class: "lambda-note", "data-role": "all-baseline" }, "λ 0: the fit kept no deviation from the baseline (config shrink_deviations), so every task's reward below is the baseline itself.")
      : null;
  fill($("heatmaps"), same, ...cards);
}

// A picture that opens full size (`open`) on a click, or from the keyboard (Tab to it, then Enter or Space).
function zoomable(img, what, open) {
  img.classList.add("zoomable");
  img.title = "Open full size";
  img.tabIndex = 0;
  img.setAttribute("role", "button");
  img.setAttribute("aria-label", `Open the ${what} full size`);
  img.addEventListener("click", open);
  img.addEventListener("keydown", (event) => {
    if (event.key !== "Enter" && event.key !== " ") return;
    event.preventDefault();
    open();
  });
}

// Fetch a picture with the key and show it from a blob: URL, kept with the view's others until released.
// Until the picture has loaded it is hidden behind a placeholder, so a slow render never shows a broken image.
async function loadImage(img, view, current, path, options) {
  const placeholder = el("div", { class: "img-placeholder", "data-role": "placeholder" }, "Rendering…");
  img.hidden = true;
  img.before(placeholder);
  img.addEventListener("load", () => {
    placeholder.remove();
    img.hidden = false;
  }, { once: true });
  try {
    const blob = await (await api(path, options)).blob();
    if (!current()) return;
    const url = URL.createObjectURL(blob);
    state.blobUrls[view].push(url);
    img.src = url;
  } catch (error) {
    placeholder.remove();
    if (current()) img.replaceWith(el("div", { class: "nopic" }, `${img.alt}: unavailable (${error.message})`));
  }
}

// The colours of the server's matrix figure (matplotlib's RdBu_r on -1..1: blue below 0, red above), sampled
// at r = -1, -0.8, …, 1 and interpolated between.
const RDBU_R = [[5, 48, 97], [32, 101, 171], [67, 147, 195], [144, 196, 221], [209, 229, 240], [247, 246, 246], [253, 219, 199], [243, 164, 129], [214, 96, 77], [177, 24, 43], [103, 0, 31]];

function correlationColour(r) {
  if (!Number.isFinite(r)) return "rgb(217, 217, 217)"; // the figure's grey for "n/a"
  const u = ((Math.min(1, Math.max(-1, r)) + 1) / 2) * (RDBU_R.length - 1);
  const i = Math.min(RDBU_R.length - 2, Math.floor(u));
  const [a, b] = [RDBU_R[i], RDBU_R[i + 1]];
  return `rgb(${a.map((c, k) => Math.round(c + (b[k] - c) * (u - i))).join(", ")})`;
}

// The matrix's colour scale: a bar from -1 to 1 with its ends and middle named.
function matrixScale() {
  const stops = RDBU_R.map((c, i) => `rgb(${c.join(", ")}) ${(100 * i) / (RDBU_R.length - 1)}%`).join(", ");
  return el(
    "div",
    { class: "matrix-scale", "data-role": "matrix-scale" },
    el("span", { class: "scale-name" }, "Pearson r"),
    el("span", {}, "−1"),
    el("i", { style: { backgroundImage: `linear-gradient(to right, ${stops})` }, role: "img", "aria-label": "colour scale: blue at −1, white at 0, red at +1" }),
    el("span", {}, "+1"),
    el("span", { class: "scale-note" }, "blue: opposite · white: unrelated · red: alike"),
  );
}

function renderMatrix(m) {
  const head = el("tr", {}, el("th", {}), m.labels.map((label) => el("th", { title: label, scope: "col" }, label)));
  const rows = m.matrix.map((row, i) =>
    el(
      "tr",
      {},
      el("th", { class: "row", title: m.labels[i], scope: "row" }, m.labels[i]),
      row.map((r) =>
        el("td", { class: "num", style: { background: correlationColour(r), color: Math.abs(r) > 0.6 ? "#fff" : "#1f2933" } }, Number.isFinite(r) ? fixed(r, 2) : "n/a"),
      ),
    ),
  );
  fill($("matrix"), el("table", { class: "matrix" }, el("thead", {}, head), el("tbody", {}, rows)), matrixScale());
}

// Per task, the states where its reward departs most from the baseline; a task whose reward is the
// baseline (λ 0, or every deviation set to zero) says so instead of listing states that depart by 0.
function renderKeyStates(tasks, all, job) {
  const heads = ["#", "state", "x, y", "reward", "baseline", "diff."];
  const tables = all.map((ks, i) => {
    const layout = layoutOfTask(ks.task_id);
    const where = (s) => {
      if (s.x === null || s.x === undefined) return "–";
      const channel = s.channel === null || s.channel === undefined ? "" : channelName(layout, s.channel);
      return `${s.x}, ${s.y}${channel ? ` (${channel})` : ""}`;
    };
    const same = ks.states.every((s) => Math.abs(s.difference) < 1e-9); // none departs: the API lists none
    const why = job && job.shrinkage === 0 ? " (λ 0: the fit kept no deviation from the baseline)" : "";
    return el(
      "table",
      { "data-task": ks.task_id },
      el("caption", {}, tasks[i].task_name || ks.task_id),
      same ? null : el("thead", {}, el("tr", {}, heads.map((h) => el("th", {}, h)))),
      el(
        "tbody",
        {},
        same
          ? el("tr", {}, el("td", { class: "empty", colspan: heads.length, "data-role": "equals-baseline" }, `This task's reward equals the baseline everywhere${why}.`))
          : ks.states.map((s) =>
              el(
                "tr",
                {},
                el("td", {}, s.rank),
                el("td", {}, s.state),
                el("td", { "data-role": "where" }, where(s)),
                el("td", { class: "num" }, fixed(s.reward, 2)),
                el("td", { class: "num" }, fixed(s.baseline, 2)),
                el("td", { class: `num ${s.difference >= 0 ? "pos" : "neg"}` }, fixed(s.difference, 2)),
              ),
            ),
      ),
    );
  });
  fill($("key-states"), ...(tables.length ? tables : [el("p", { class: "empty" }, "No tasks.")]));
}

// ---- motion readout ------------------------------------------------------------------------------

// The kinematic descriptors of GET /v1/demonstrators/{id}/motion-summary, in the API's order.
const DESCRIPTORS = [
  ["peak_reach", "peak reach"],
  ["path_length", "path length"],
  ["deviation", "deviation"],
  ["time_to_peak_s", "time to peak"],
  ["mean_speed", "mean speed"],
];

function loading() {
  return el("p", { class: "empty", "data-role": "loading" }, "Loading…");
}

function unavailable(error) {
  return el("p", { class: "empty" }, `Unavailable: ${error.message}`);
}

// Whether a 95 % interval leaves out 0 (null bounds: one repetition, no interval).
function clearOfZero(v, format) {
  // Judged on the bounds as printed: an interval shown as [-0.013, 0.000] is not marked as leaving out 0.
  if (v.low === null || v.high === null) return false;
  return Number(format(v.low)) > 0 || Number(format(v.high)) < 0;
}

// A mean with its 95 % interval below it (none with a single repetition), in its column's format.
function intervalCell(v, className = "", format = fmt) {
  return el(
    "td",
    { class: `num ${className}` },
    format(v.mean),
    el("div", { class: "ci" }, v.low === null || v.high === null ? "" : `[${format(v.low)}, ${format(v.high)}]`),
  );
}

// The format of each column of a table of intervals: {key: format}, from every mean and bound in the column.
function intervalFormats(rows, keys) {
  return Object.fromEntries(keys.map((key) => [key, columnFormat(rows.flatMap((row) => [row[key].mean, row[key].low, row[key].high]))]));
}

// "peak reach, path length, deviation: x, y units (as uploaded) · …": each unit once, with what it measures.
function unitsNote(units) {
  const groups = new Map();
  for (const [key, label] of DESCRIPTORS) {
    if (units[key]) groups.set(units[key], [...(groups.get(units[key]) || []), label]);
  }
  return [...groups].map(([unit, labels]) => `${labels.join(", ")}: ${unit}`).join(" · ");
}

async function showMotion(id, { scroll = false } = {}) {
  const call = ++state.motionCall;
  const current = () => call === state.motionCall;
  state.motion = id;
  for (const node of document.querySelectorAll("#demonstrators .dem")) {
    node.classList.toggle("selected", node.dataset.demonstrator === id);
  }
  const section = $("motion");
  section.hidden = false;
  section.dataset.demonstrator = id;
  $("motion-title").textContent = `Motion readout of ${demonstratorName(id)}`;
  $("motion-meta").textContent = "";
  fill($("kinematics"), loading());
  fill($("learned"));
  renderPartners(id);
  if (scroll) section.scrollIntoView({ block: "start" });
  showComparison();
  let box = $("kinematics");
  try {
    const summary = await getJson(`/v1/demonstrators/${encodeURIComponent(id)}/motion-summary`);
    if (!current()) return;
    $("motion-meta").textContent = `${summary.n_recordings} recording${summary.n_recordings === 1 ? "" : "s"}`;
    renderKinematics(summary);
    box = $("learned");
    fill(box, loading());
    await renderLearned(summary.learned, current);
  } catch (error) {
    if (!current()) return;
    fill(box, unavailable(error));
    reportError(error);
  }
}

function renderKinematics(summary) {
  const formats = intervalFormats(summary.directions, DESCRIPTORS.map(([key]) => key));
  const table = el(
    "table",
    { class: "readout kinematics" },
    el(
      "thead",
      {},
      el("tr", {}, el("th", {}, "direction"), el("th", { title: "out-and-back movements" }, "n"), DESCRIPTORS.map(([key, label]) => el("th", { title: summary.units[key] }, label))),
    ),
    el(
      "tbody",
      {},
      summary.directions.map((d) =>
        el("tr", { "data-direction": d.direction }, el("th", { class: "row" }, d.direction), el("td", { class: "num" }, d.n_segments), DESCRIPTORS.map(([key]) => intervalCell(d[key], "", formats[key]))),
      ),
    ),
  );
  fill($("kinematics"), table, el("p", { class: "units" }, unitsNote(summary.units)));
}

// Table I of the paper, as the API reads it out: per direction task of the job, the states its
// demonstrations visit, the ring-centred baseline there, the task reward's r with the baseline there, and
// (where the tasks carry a true reward) the task reward's r with it from the job's rewards listing.
async function renderLearned(learned, current) {
  if (!learned) {
    fill($("learned"), el("p", { class: "empty" }, "No job on this demonstrator has succeeded yet: the readout of its learned rewards shows here once one has."));
    return;
  }
  const rewards = await getJson(`/v1/jobs/${encodeURIComponent(learned.job_id)}/rewards`);
  if (!current()) return;
  const truth = new Map(rewards.tasks.map((t) => [t.task_id, t.truth_pearson]));
  const withTruth = learned.directions.some((d) => truth.get(d.task_id) !== null && truth.get(d.task_id) !== undefined);
  const verdict = renderAgreement(learned.agreement);
  const preference = learned.agreement.verdict === "agrees" ? "baseline, ring-centred" : "baseline, ring-centred (not a preference)";
  const heads = ["direction", "visited states", preference, "r(task, baseline)", "path bend (no fit)"];
  const table = learned.directions.length
    ? el(
        "table",
        { class: "readout learned" },
        el("thead", {}, el("tr", {}, [...heads, ...(withTruth ? ["r vs truth"] : [])].map((h) => el("th", {}, h)))),
        el(
          "tbody",
          {},
          learned.directions.map((d) =>
            el(
              "tr",
              { "data-direction": d.direction },
              el("th", { class: "row" }, d.direction),
              el("td", { class: "num" }, d.n_visited_states),
              el("td", { class: `num ${d.baseline_ring_centred === null ? "" : d.baseline_ring_centred >= 0 ? "pos" : "neg"}` }, fmt(d.baseline_ring_centred, 3)),
              el("td", { class: "num" }, fmt(d.task_baseline_pearson, 2)),
              el("td", { class: "num", "data-role": "path-bend" }, fmt(d.path_bend, 2)),
              withTruth ? el("td", { class: "num" }, fmt(truth.get(d.task_id), 2)) : null,
            ),
          ),
        ),
      )
    : el("p", { class: "empty" }, "The job has no direction tasks on a velocity grid, so there is nothing to read out per direction.");
  fill($("learned"),
    el(
      "div",
      { class: "learned-job" },
      "job ",
      el("span", { class: "id" }, learned.job_id),
      " ",
      el("button", { class: "small quiet", "data-action": "results", onclick: () => showResults(learned.job_id, { scroll: true }) }, "Heatmaps"),
    ),
    verdict,
    learned.recordings_after_job?.length
      ? el(
          "p",
          { class: "caveat", "data-role": "stale" },
          `${learned.recordings_after_job.length} recording(s) came after this job: the paths and reach here include them, the fit never saw them. Submit a new job to learn from them.`,
        )
      : null,
    table,
    el("p", { class: "caveat", "data-role": "caveat" }, learned.caveat),
  );
}

// The verdict on the learned readout against the recordings, shown above it: only "agrees" lets the table be
// read as the patient's preference (docs/motion.md).
function renderAgreement(agreement) {
  const headline = {
    agrees: "The learned readout agrees with the recordings.",
    disagrees: "The learned readout contradicts the recordings: it is not the patient's preference.",
    undetermined: "The recordings do not confirm the learned readout: it is not shown to be the patient's preference.",
  }[agreement.verdict];
  return el(
    "div",
    { class: `agreement ${agreement.verdict}`, "data-role": "agreement", "data-verdict": agreement.verdict },
    el("strong", {}, headline),
    " ",
    // The API's detail may open with the same sentence: it is said once.
    agreement.detail.startsWith(headline) ? agreement.detail.slice(headline.length).trim() : agreement.detail,
  );
}

// The other demonstrators with recorded movements, as the sessions to compare with (standing trials alone
// give nothing to compare per direction); the choice is kept if it still fits.
function renderPartners(id) {
  $("compare-label").textContent = `${demonstratorName(id)} (a), against b =`;
  const select = $("compare-with");
  const previous = select.value;
  const others = [...state.demonstrators.values()].filter((d) => d.id !== id && hasMovements(d));
  fill(select, ...others.map((d) => el("option", { value: d.id }, d.name)));
  if (others.some((d) => d.id === previous)) select.value = previous;
  select.disabled = others.length === 0;
}

// The comparison of the motion readout's demonstrator (a) with the one picked (b). Only the latest call draws:
// a new pick or a closed readout aborts the requests of the one before, and any answer of theirs that still
// arrives (an error too) is dropped.
async function showComparison() {
  const call = ++state.comparisonCall;
  state.comparisonAbort?.abort();
  const controller = new AbortController();
  state.comparisonAbort = controller;
  const current = () => call === state.comparisonCall;
  releaseBlobs("comparison");
  const a = state.motion;
  const b = $("compare-with").value;
  const box = $("comparison");
  if (!a || !b) {
    delete box.dataset.b;
    fill(box, el("p", { class: "empty" }, "Upload recorded movements for another demonstrator (another session) to compare with."));
    return;
  }
  box.dataset.b = b;
  fill(box, loading());
  const options = { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify({ a, b }), signal: controller.signal };
  try {
    const comparison = await getJson("/v1/motion-comparisons", options);
    if (!current()) return;
    const img = el("img", { alt: `Comparison figure of ${comparison.b.name} and ${comparison.a.name}` });
    fill(box, el("figure", { class: "comparison-figure" }, img), renderDifferences(comparison));
    loadImage(img, "comparison", current, comparison.links.png, options);
  } catch (error) {
    if (!current()) return;
    fill(box, unavailable(error));
    reportError(error);
  }
}

// Millimetres per length unit: lengths in these are shown in mm while they are under a metre.
const MM_PER_UNIT = { m: 1000, cm: 10, mm: 1 };

// A unit as a column head shows it: "x, y units" for "x, y units (as uploaded)".
function shortUnit(text) {
  return (text || "").replace(/\s*\(as uploaded\)\s*$/, "");
}

// One format for a column of differences: fixed decimals enough for two significant digits of its smallest
// value that is more than rounding noise (1 % of the column's largest or more), `least` decimals at least and
// 6 at most (`least` for a column of rounding noise); exponents only for a column of large values; "–" for a
// missing one.
function differenceFormat(values, least) {
  const finite = values.filter((v) => typeof v === "number" && Number.isFinite(v)).map(Math.abs);
  const top = finite.length ? Math.max(...finite) : 0;
  if (top >= 1e5) return (x) => (typeof x === "number" && Number.isFinite(x) ? x.toExponential(2) : "–");
  if (top < 1e-6) return (x) => fixed(x, least); // rounding noise
  const smallest = Math.min(...finite.filter((v) => v >= top * 0.01));
  const digits = Math.min(6, Math.max(least, 1 - Math.floor(Math.log10(smallest))));
  return (x) => fixed(x, digits);
}

// How the comparison shows one descriptor's differences: lengths (and speeds) in m or cm as mm while the
// column stays under a metre, with the unit named; {unit, title, format}.
function differenceColumn(c, key) {
  const unitText = c.units[key] || "";
  const raw = c.directions.flatMap((d) => [d[`${key}_diff`].mean, d[`${key}_diff`].low, d[`${key}_diff`].high]);
  const perMm = MM_PER_UNIT[c.unit];
  const isLength = perMm !== undefined && (unitText === c.unit || unitText.startsWith(`${c.unit} `));
  const top = Math.max(0, ...raw.filter((v) => typeof v === "number" && Number.isFinite(v)).map(Math.abs));
  const factor = isLength && top * perMm < 1000 ? perMm : 1;
  const scale = (x) => (typeof x === "number" ? x * factor : x);
  const format = differenceFormat(raw.map(scale), isLength ? 1 : 3);
  return {
    unit: isLength && factor !== 1 ? `mm${unitText.slice(c.unit.length)}` : shortUnit(unitText),
    title: unitText,
    format: (x) => format(scale(x)),
  };
}

function renderDifferences(c) {
  const columns = Object.fromEntries(DESCRIPTORS.map(([key]) => [key, differenceColumn(c, key)]));
  // Each side's name with its colour in the figure (app.css: the figure's colours).
  const side = (which, name) => el("span", { class: "side", "data-side": which }, el("i"), name);
  return el(
    "table",
    { class: "readout differences" },
    el(
      "caption",
      {},
      side("b", c.b.name),
      " − ",
      side("a", c.a.name),
      " (b − a) per direction; as in the figure: red, the 95 % interval leaves out 0; grey, it holds 0",
    ),
    el(
      "thead",
      {},
      el(
        "tr",
        {},
        el("th", {}, "direction"),
        el("th", { title: "movements of a, of b" }, "n a, b"),
        DESCRIPTORS.map(([key, label]) =>
          el("th", { title: columns[key].title, "data-key": key }, `Δ ${label}`, columns[key].unit ? el("div", { class: "unit" }, `(${columns[key].unit})`) : null),
        ),
      ),
    ),
    el(
      "tbody",
      {},
      c.directions.map((d) =>
        el(
          "tr",
          { "data-direction": d.direction },
          el("th", { class: "row" }, d.direction),
          el("td", { class: "num" }, `${d.n_a}, ${d.n_b}`),
          DESCRIPTORS.map(([key]) => {
            const v = d[`${key}_diff`];
            const format = columns[key].format;
            return intervalCell(v, clearOfZero(v, format) ? (v.mean > 0 ? "diff pos clear" : "diff neg clear") : "diff", format);
          }),
        ),
      ),
    ),
  );
}

// ---- webhooks ------------------------------------------------------------------------------------

const DELIVERY_EVENTS = ["job.succeeded", "job.failed", "job.cancelled"];

async function loadWebhooks(generation) {
  const call = ++state.webhooksCall;
  const hooks = await getAll("/v1/webhooks");
  // The listing leaves the deliveries out: each webhook's own page has its latest ones.
  const detailed = await Promise.all(
    hooks.map((h) =>
      getJson(`/v1/webhooks/${encodeURIComponent(h.id)}`).catch((error) => {
        if (error instanceof ApiError && error.status === 404) return null; // deleted meanwhile
        throw error;
      }),
    ),
  );
  if (generation !== state.generation || call !== state.webhooksCall) return;
  renderWebhooks(detailed.filter(Boolean));
}

function when(iso) {
  return iso ? new Date(iso).toLocaleString() : "–";
}

// The newest delivery's state, with the counts of the latest ones the API keeps.
function deliveryState(deliveries) {
  if (deliveries.length === 0) return el("span", { class: "meta" }, "no deliveries yet");
  const d = deliveries[0];
  const detail = {
    delivered: `${d.type} · ${when(d.delivered_at)}`,
    pending: `${d.type} · attempt ${d.attempts}, next ${when(d.next_attempt_at)}`,
    failed: `${d.type} · gave up after ${d.attempts} attempts`,
  }[d.status];
  const counts = ["delivered", "pending", "failed"]
    .map((status) => [status, deliveries.filter((x) => x.status === status).length])
    .filter(([, n]) => n > 0)
    .map(([status, n]) => `${n} ${status}`)
    .join(", ");
  return el(
    "div",
    {},
    el("span", { class: `badge ${d.status}`, "data-role": "delivery" }, d.status),
    " ",
    el("span", { class: "meta" }, detail),
    d.last_error && d.status !== "delivered" ? el("div", { class: "error" }, d.last_error) : null,
    deliveries.length > 1 ? el("div", { class: "meta" }, `latest ${deliveries.length}: ${counts}`) : null,
  );
}

function renderWebhooks(hooks) {
  fill($("webhooks"),
    ...hooks.map((h) =>
      el(
        "tr",
        { "data-webhook": h.id },
        el("td", { class: "url" }, el("div", { title: h.url }, h.url), el("div", { class: "id" }, h.id)),
        el("td", {}, DELIVERY_EVENTS.filter((e) => h.events.includes(e)).map((e) => e.replace("job.", "")).join(", ")),
        el("td", {}, deliveryState(h.deliveries)),
        el("td", { class: "bar-text" }, when(h.created_at)),
        el("td", { class: "actions" }, el("button", { class: "danger small", "data-action": "delete", onclick: () => deleteWebhook(h) }, "Delete")),
      ),
    ),
  );
  $("webhooks-empty").hidden = hooks.length > 0;
}

function formError(text) {
  $("webhook-error").textContent = text;
  $("webhook-error").hidden = !text;
}

async function addWebhook(event) {
  event.preventDefault();
  const generation = state.generation;
  const events = [...$("webhook-form").querySelectorAll("input[name=events]:checked")].map((i) => i.value);
  if (events.length === 0) {
    formError("Tick at least one event.");
    return;
  }
  formError("");
  $("webhook-add").disabled = true;
  try {
    const created = await getJson("/v1/webhooks", {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ url: $("webhook-url").value.trim(), events }),
    });
    if (generation !== state.generation) return;
    $("webhook-url").value = "";
    showSecret(created);
    await loadWebhooks(generation);
  } catch (error) {
    if (generation !== state.generation) return;
    if (error instanceof ApiError && error.status !== 401) formError(`${error.status}: ${error.message}`);
    else reportError(error);
  } finally {
    $("webhook-add").disabled = false;
  }
}

// The API shows a webhook's signing secret in the creation answer only; so does the page, until "Done".
function showSecret(created) {
  const value = el("code", { class: "secret-value", "data-role": "secret" }, created.secret);
  const copy = el("button", { class: "small", type: "button", "data-action": "copy-secret", onclick: () => copySecret(value, copy) }, "Copy");
  const box = $("webhook-secret");
  box.dataset.webhook = created.id;
  fill(box,
    el(
      "div",
      {},
      el("strong", {}, "Signing secret of the new webhook, shown this once: copy it now. "),
      "The receiver verifies each delivery's ",
      el("code", {}, "webhook-signature"),
      " header with it (Standard Webhooks); it cannot be read again, only replaced by a new webhook.",
    ),
    el("div", { class: "secret-row" }, value, copy, el("button", { class: "small quiet", type: "button", "data-action": "dismiss-secret", onclick: hideSecret }, "Done")),
  );
  box.hidden = false;
}

function hideSecret() {
  const box = $("webhook-secret");
  fill(box);
  delete box.dataset.webhook;
  box.hidden = true;
}

async function copySecret(node, button) {
  try {
    await navigator.clipboard.writeText(node.textContent);
    button.textContent = "Copied";
  } catch (_) {
    // No clipboard access (a page served over plain http from another host): select it for Ctrl+C.
    const range = document.createRange();
    range.selectNodeContents(node);
    getSelection().removeAllRanges();
    getSelection().addRange(range);
    button.textContent = "Selected: press Ctrl+C";
  }
}

async function deleteWebhook(hook) {
  if (!confirm(`Delete the webhook to ${hook.url}? Deliveries not yet sent are dropped.`)) return;
  const generation = state.generation;
  try {
    await api(`/v1/webhooks/${encodeURIComponent(hook.id)}`, { method: "DELETE" });
    if (generation !== state.generation) return;
    if ($("webhook-secret").dataset.webhook === hook.id) hideSecret();
    await loadWebhooks(generation);
  } catch (error) {
    if (generation === state.generation) reportError(error);
  }
}

// ---- start ---------------------------------------------------------------------------------------

document.addEventListener("DOMContentLoaded", () => {
  $("key-form").addEventListener("submit", (event) => {
    event.preventDefault();
    useKey($("key-input").value);
  });
  $("key-forget").addEventListener("click", forgetKey);
  $("refresh").addEventListener("click", () => {
    const generation = state.generation;
    const { run, selected, motion, sway } = state;
    loadEverything()
      .then(() => Promise.all([jobExists(run), jobExists(selected)]))
      .then(([runThere, selectedThere]) => {
        if (generation !== state.generation) return;
        // A job deleted elsewhere closes its run page and results, and a demonstrator's panels close with it;
        // the message says so in place of any error their late answers reported. A job on another page of
        // the list stays.
        const gone = new Set();
        if (run !== null && state.run === run && !runThere) {
          hideRun();
          gone.add(`job ${run}`);
        }
        if (selected !== null && state.selected === selected) {
          if (selectedThere) showResults(selected);
          else {
            hideResults();
            gone.add(`job ${selected}`);
          }
        }
        redrawPanels();
        for (const id of [motion, sway]) if (id !== null && !state.demonstrators.has(id)) gone.add(`demonstrator ${id}`);
        if (gone.size) showMessage(`Deleted elsewhere: ${[...gone].join(", ")}; its panels are closed.`, "info");
      })
      .catch((error) => {
        if (generation === state.generation) reportError(error);
      });
  });
  $("compare-with").addEventListener("change", showComparison);
  $("webhook-form").addEventListener("submit", addWebhook);
  if (state.key) useKey(state.key);
});

// ---- quiet standing ------------------------------------------------------------------------------

// The sway measures shown, with their labels and whether they are lengths (L), areas (A) or neither.
const SWAY_MEASURES = [
  ["area95", "95 % ellipse area", "A"],
  ["mean_velocity", "mean velocity", "L/s"],
  ["path_length", "path length", "L"],
  ["mean_distance", "mean distance", "L"],
  ["rms_x", "RMS x", "L"],
  ["rms_y", "RMS y", "L"],
  ["range_x", "range x", "L"],
  ["range_y", "range y", "L"],
  ["sway_area_per_second", "sway area / s", "A/s"],
  ["mean_frequency", "mean frequency", "Hz"],
  ["f95", "95 % power frequency", "Hz"],
];

function swayUnit(kind, units) {
  const length = units || "units";
  return { A: `${length}²`, "A/s": `${length}²/s`, L: length, "L/s": `${length}/s`, Hz: "Hz" }[kind];
}

// How sway measures in ``units`` are shown: trials in metres in millimetres (their sway is a few mm, which
// three decimals of a metre would hide), others as they are. {unit(kind), value(x, kind)}.
function swayScale(units) {
  const toMm = units === "m";
  const factor = { A: 1e6, "A/s": 1e6, L: 1e3, "L/s": 1e3, Hz: 1 };
  return {
    unit: (kind) => swayUnit(kind, toMm ? "mm" : units),
    value: (x, kind) => (toMm && typeof x === "number" ? x * factor[kind] : x),
  };
}

function swayKind(key) {
  return SWAY_MEASURES.find(([k]) => k === key)[2];
}

// A "Sway" button for a demonstrator with standing trials (none otherwise).
function swayButton(d) {
  if (standingTrials(d).length === 0) return null;
  return el("button", { class: "small quiet", "data-action": "sway", onclick: () => showSway(d.id, { scroll: true }) }, "Sway");
}

// The sway panel of a demonstrator: one trial's measures and COP picture (``trial``, else the newest), and its
// trials compared by label.
async function showSway(id, { scroll = false, trial = null } = {}) {
  const view = ++state.swayView;
  state.sway = id;
  const d = state.demonstrators.get(id);
  const trials = d ? standingTrials(d) : [];
  const section = $("sway");
  section.hidden = false;
  section.dataset.demonstrator = id;
  $("sway-title").textContent = `Quiet standing of ${demonstratorName(id)}`;
  $("sway-meta").textContent = `${trials.length} standing trial${trials.length === 1 ? "" : "s"}`;
  const select = $("sway-recording");
  fill(select,
    ...trials.map((r) => el("option", { value: r.id, title: r.id }, `${recordingName(r)}${labelsText(r.metadata)}`)),
  );
  const shown = trials.find((r) => r.id === trial) || trials[0];
  if (shown) select.value = shown.id;
  select.onchange = () => showSwayTrial(select.value);
  if (scroll) section.scrollIntoView({ block: "start" });
  if (shown) showSwayTrial(shown.id);
  await showSwayGroups(id, trials, () => view === state.swayView);
}

function labelsText(metadata) {
  const entries = Object.entries(metadata || {});
  return entries.length ? ` (${entries.map(([k, v]) => `${k}: ${v}`).join(", ")})` : "";
}

async function showSwayTrial(recordingId) {
  const call = ++state.swayCall;
  const current = () => call === state.swayCall;
  releaseBlobs("sway");
  fill($("sway-measures"), loading());
  fill($("sway-picture"), loading());
  try {
    const sway = await getJson(`/v1/recordings/${encodeURIComponent(recordingId)}/sway`);
    if (!current()) return;
    // A measure the API flags (coarse: `caveats`; null: `not_estimated`) carries a star and its reason.
    const swayNote = (key) => sway.caveats?.[key] ?? sway.not_estimated?.[key];
    const notes = [...new Set(SWAY_MEASURES.map(([key]) => swayNote(key)).filter(Boolean))];
    const scale = swayScale(sway.units);
    const trial = $("sway-recording").selectedOptions[0]?.textContent || recordingId;
    fill($("sway-measures"),
      el(
        "table",
        { class: "readout sway-measures" },
        el("caption", {}, `${trial}${sway.units ? "" : " · lengths in the trial's own units (uploaded without a unit)"}`),
        el("thead", {}, el("tr", {}, el("th", {}, "measure"), el("th", {}, "value"), el("th", {}, "unit"))),
        el("tbody", {}, SWAY_MEASURES.map(([key, label, kind]) =>
          el(
            "tr",
            { "data-measure": key },
            el("th", {}, label),
            el("td", { class: "num", title: swayNote(key) ?? "" }, fmt(scale.value(sway.descriptors[key], kind)) + (swayNote(key) ? " *" : "")),
            el("td", { class: "meta" }, scale.unit(kind)),
          ),
        )),
      ),
      el("p", { class: "sub" }, `${sway.n_samples} samples at ${Number(sway.rate_hz.toPrecision(6))} Hz over ${fmt(sway.duration_s, 3)} s`),
      notes.length ? el("p", { class: "caveat", "data-role": "sway-caveat" }, `* ${notes.join("; ")}`) : null,
      sway.caveats?.samples ? el("p", { class: "caveat", "data-role": "sway-samples-caveat" }, sway.caveats.samples) : null,
    );
    // The picture goes in once it is being fetched: behind loadImage's placeholder, never a broken image.
    const img = el("img", { alt: "COP path with its 95 % ellipse", "data-recording": recordingId });
    fill($("sway-picture"), img);
    loadImage(img, "sway", current, `/v1/recordings/${encodeURIComponent(recordingId)}/sway?format=png`);
  } catch (error) {
    if (!current()) return;
    fill($("sway-measures"), unavailable(error));
    fill($("sway-picture"));
    if (error instanceof ApiError && error.status === 401) reportError(error);
  }
}

// Trials grouped by `vision` when they carry it, else by their first label; the Romberg quotient for vision.
async function showSwayGroups(id, trials, current) {
  const box = $("sway-groups");
  const labels = [...new Set(trials.flatMap((r) => Object.keys(r.metadata || {})))];
  const by = labels.includes("vision") ? "vision" : labels[0];
  if (!by) {
    fill(box, el("p", { class: "empty" }, "Label the trials (metadata such as {\"vision\": \"closed\"}) to compare conditions."));
    return;
  }
  fill(box, loading());
  try {
    const summary = await getJson(`/v1/demonstrators/${encodeURIComponent(id)}/sway-summary?by=${encodeURIComponent(by)}`);
    if (!current()) return;
    const shown = ["area95", "mean_velocity", "mean_frequency"];
    const scale = swayScale(summary.unit);
    const estimate = (v, kind) => {
      const value = (x) => fmt(kind ? scale.value(x, kind) : x);
      return el("td", { class: "num" }, value(v.value), el("div", { class: "ci" }, v.low === null || v.high === null ? "" : `[${value(v.low)}, ${value(v.high)}]`));
    };
    const rows = summary.groups.map((g) => el("tr", { "data-group": g.label }, el("th", { class: "row" }, `${by}: ${g.label} (${g.n})`), ...shown.map((m) => estimate(g.measures[m], swayKind(m)))));
    // The quotient is of like over like: a ratio without a unit, never scaled.
    if (summary.romberg) rows.push(el("tr", { "data-group": "romberg" }, el("th", { class: "row" }, "Romberg quotient (closed / open, no unit)"), ...shown.map((m) => estimate(summary.romberg[m], null))));
    const names = new Map(trials.map((r) => [r.id, recordingName(r)]));
    const left = summary.unlabelled || [];
    fill(box,
      el(
        "table",
        { class: "readout sway-groups" },
        el("caption", {}, `Standing trials grouped by their label “${by}” (the number of trials in brackets)`),
        el(
          "thead",
          {},
          el(
            "tr",
            {},
            el("th", {}, by),
            ...shown.map((m) => el("th", { "data-measure": m }, SWAY_MEASURES.find(([k]) => k === m)[1], el("div", { class: "unit" }, `(${scale.unit(swayKind(m))})`))),
          ),
        ),
        el("tbody", {}, rows),
      ),
      left.length
        ? el("p", { class: "units", "data-role": "sway-unlabelled" }, `Left out, without a “${by}” label: ${left.map((id) => names.get(id) || id).join(", ")}.`)
        : null,
    );
  } catch (error) {
    if (current()) fill(box, unavailable(error));
  }
}

// ---- job list: filters and paging ----------------------------------------------------------------

const JOBS_PER_PAGE = 15;

// One page of the lab's jobs under the filters (status, demonstrator), at the cursor of the page shown.
async function jobsPage() {
  const query = new URLSearchParams({ limit: String(JOBS_PER_PAGE) });
  const status = $("filter-status").value;
  const demonstrator = $("filter-demonstrator").value;
  if (status) query.set("status", status);
  if (demonstrator) query.set("demonstrator_id", demonstrator);
  const cursor = state.cursors[state.cursors.length - 1];
  if (cursor) query.set("cursor", cursor);
  const body = await getJson(`/v1/jobs?${query}`);
  return { jobs: body.data, nextCursor: body.has_more ? body.next_cursor : null };
}

// Remove the rows (and stop following the jobs) that the page shown no longer lists.
function dropRowsNotIn(ids) {
  for (const [id, row] of state.rows) {
    if (ids.has(id)) continue;
    row.tr.remove();
    row.errorTr.remove();
    state.rows.delete(id);
    state.jobs.delete(id);
    state.watching.get(id)?.abort();
    state.watching.delete(id);
  }
}

function renderPager() {
  $("jobs-page").textContent = `page ${state.cursors.length}`;
  $("jobs-prev").disabled = state.cursors.length === 1;
  $("jobs-next").disabled = !state.nextCursor;
}

// Show the first page again (after a filter changed) or the next or previous one.
function turnPage(how) {
  if (how === "next" && state.nextCursor) state.cursors.push(state.nextCursor);
  else if (how === "prev" && state.cursors.length > 1) state.cursors.pop();
  else if (how === "first") state.cursors = [null];
  loadJobs(state.generation).catch(reportError);
}

function renderDemonstratorFilter() {
  const select = $("filter-demonstrator");
  const previous = select.value;
  fill(select,
    el("option", { value: "" }, "any"),
    ...[...state.demonstrators.values()].map((d) => el("option", { value: d.id }, d.name)),
  );
  if (state.demonstrators.has(previous)) select.value = previous;
}

// A setting's default in the schema (the schema leaves out a default of null).
function defaultOf(schema) {
  return schema.default === undefined ? null : schema.default;
}

// The settings of a job's config that differ from JobConfig's defaults, as [name, value] pairs.
function configDifferences(config) {
  const props = state.configSchema || {};
  return Object.entries(config || {}).filter(
    ([name, value]) => !(name in props) || JSON.stringify(defaultOf(props[name])) !== JSON.stringify(value),
  );
}

function configSummary(config) {
  const differences = configDifferences(config);
  if (!state.configSchema) return el("span", { class: "meta" }, "…");
  if (differences.length === 0) return el("span", { class: "meta" }, "defaults");
  return differences.map(([name, value]) => el("span", { class: "chip", title: `${name} = ${JSON.stringify(value)}` }, `${name}=${JSON.stringify(value)}`));
}

function attemptsText(job) {
  const took = duration(job.started_at, job.finished_at);
  return `attempt ${job.attempts}/${job.max_attempts}${took ? ` · ${took} in all` : ""}`;
}

// "12.3 s" or "4 min 5 s" between two ISO times (until now while the second is missing); "" before the start.
function duration(from, to) {
  if (!from) return "";
  const seconds = ((to ? new Date(to) : new Date()) - new Date(from)) / 1000;
  return seconds < 60 ? `${seconds.toFixed(1)} s` : `${Math.floor(seconds / 60)} min ${Math.round(seconds % 60)} s`;
}

// JobConfig's properties, read once from the OpenAPI document (it needs no key).
async function loadConfigSchema() {
  if (state.configSchema) return;
  const response = await fetch(`${ROOT}/openapi.json`);
  const spec = await response.json();
  state.configSchema = spec.components.schemas.JobConfig.properties;
}

// ---- run page: facts, settings, loss curve, downloads --------------------------------------------

async function showRun(id, { scroll = false } = {}) {
  const call = ++state.runCall;
  state.run = id;
  state.history = null;
  for (const [jobId, row] of state.rows) row.tr.className = jobId === id || jobId === state.selected ? "selected" : "";
  const section = $("run");
  section.hidden = false;
  section.dataset.job = id;
  fill($("loss-curve"), loading());
  fill($("downloads"));
  if (scroll) section.scrollIntoView({ block: "start" });
  try {
    const [job, history] = await Promise.all([
      getJson(`/v1/jobs/${encodeURIComponent(id)}`),
      getJson(`/v1/jobs/${encodeURIComponent(id)}/history`),
    ]);
    if (call !== state.runCall) return;
    state.history = historyState(id, history);
    state.jobs.set(id, job);
    renderRun(job, null);
    if (job.status === "succeeded" && state.selected !== id) showResults(id);
  } catch (error) {
    if (call === state.runCall) reportError(error);
  }
}

// The run page's curve from a `GET /v1/jobs/{id}/history` answer: every step ("steps") or samples.
function historyState(id, history) {
  return { jobId: id, attempt: history.attempt, maxSteps: history.max_steps, bestStep: history.best_step, source: history.source || "samples", points: history.points };
}

// Once the run page's job has succeeded, its curve is read again: every step of the fit, not the samples.
async function loadStepHistory(id) {
  const h = state.history;
  if (!h || h.jobId !== id || h.source !== "samples" || h.reloading) return;
  h.reloading = true;
  const call = state.runCall;
  try {
    const history = await getJson(`/v1/jobs/${encodeURIComponent(id)}/history`);
    if (call !== state.runCall || state.run !== id) return;
    state.history = historyState(id, history);
    drawLossCurve($("loss-curve"), state.history);
  } catch (error) {
    h.reloading = false;
    if (call === state.runCall) reportError(error);
  }
}

// Redraw the run page of ``job``; the downloads are read again only when the job has just succeeded.
function renderRun(job, previous) {
  $("run-title").textContent = `Run ${job.id}`;
  fill($("run-status"), el("span", { class: `badge ${job.status}`, "data-role": "status" }, job.status));
  const fact = (name, value, attrs = {}) => [el("dt", {}, name), el("dd", attrs, value)];
  const p = job.progress;
  fill($("run-facts"),
    ...fact("demonstrator", demonstratorName(job.demonstrator_id)),
    ...fact("tasks", job.task_ids.map((t) => taskName(job.demonstrator_id, t)).join(", ")),
    ...fact("steps", p ? `${p.step} of ${p.max_steps}` : "–"),
    ...fact("best step", job.best_step ?? "–"),
    ...fact("shrinkage", shrinkageText(job.shrinkage), { "data-role": "shrinkage", title: SHRINKAGE_TITLE }),
    ...fact("sparsity", sparsityText(job.sparsity), { "data-role": "sparsity", title: SHRINKAGE_TITLE }),
    ...fact("attempts", `${job.attempts} of ${job.max_attempts}`),
    ...fact("created", when(job.created_at)),
    ...fact("started", when(job.started_at)),
    ...fact("finished", when(job.finished_at)),
    ...fact("run time", duration(job.started_at, job.finished_at) || "–"),
    ...(job.error ? fact("error", job.error) : []),
  );
  renderRunConfig(job.config);
  if (state.history && state.history.jobId === job.id) {
    state.history.bestStep = job.best_step;
    drawLossCurve($("loss-curve"), state.history);
    if (job.status === "succeeded") loadStepHistory(job.id);
  }
  const succeeded = job.status === "succeeded";
  if (succeeded && (!previous || previous.status !== "succeeded" || !$("downloads").firstChild)) renderDownloads(job);
  if (!succeeded) fill($("downloads"), el("p", { class: "empty" }, downloadsLater(job)));
}

const SHRINKAGE_TITLE = "Each task reward is the baseline + λ·S_q(the task's learned reward − the baseline), S_q setting the smallest share q of the deviations to zero; λ and q chosen by held-out likelihood (config shrink_deviations)";

// The λ that pulled a job's task rewards toward the baseline, in words ("–" before success and with the tabular methods).
function shrinkageText(shrinkage) {
  if (shrinkage === null || shrinkage === undefined) return "–";
  const pulled = { 0: "every task reward is the baseline", 0.25: "task rewards pulled three quarters of the way to the baseline", 0.5: "task rewards pulled half-way to the baseline", 0.75: "task rewards pulled a quarter of the way to the baseline", 1: "deviations from the baseline kept at full size" }[shrinkage];
  return `λ ${shrinkage}` + (pulled ? ` (${pulled})` : "");
}

// The share q of each task's deviations from the baseline set to zero, in words ("–" as for the shrinkage).
function sparsityText(sparsity) {
  if (sparsity === null || sparsity === undefined) return "–";
  if (sparsity === 0) return "q 0 (every state's deviation from the baseline kept)";
  return `q ${sparsity} (the smallest ${+(100 * sparsity).toFixed(1)} % of each task's deviations from the baseline set to zero)`;
}

function downloadsLater(job) {
  const inputs = "the MDP arrays and demonstrations are listed below once it has succeeded";
  const ended = { failed: "failed", cancelled: "was cancelled" }[job.status];
  return ended ? `The job ${ended}: it has no learned rewards.` : `Learned rewards, ${inputs}.`;
}

function taskName(demonstratorId, taskId) {
  const d = state.demonstrators.get(demonstratorId);
  const t = d && d.tasks.find((x) => x.id === taskId);
  return t ? t.name : taskId;
}

function renderRunConfig(config) {
  const props = state.configSchema || {};
  const differences = configDifferences(config);
  fill($("run-config"),
    differences.length
      ? el(
          "table",
          { class: "readout config-table" },
          el("thead", {}, el("tr", {}, el("th", {}, "setting"), el("th", {}, "value"), el("th", {}, "default"))),
          el(
            "tbody",
            {},
            differences.map(([name, value]) =>
              el("tr", { "data-setting": name }, el("th", { class: "row", title: props[name]?.description || "" }, name), el("td", {}, JSON.stringify(value)), el("td", { class: "meta" }, name in props ? JSON.stringify(defaultOf(props[name])) : "–")),
            ),
          ),
        )
      : el("p", { class: "empty" }, "Every setting at its default."),
    el("details", { class: "full-config" }, el("summary", {}, "All settings"), el("pre", {}, JSON.stringify(config, null, 1))),
  );
}

// A progress event of the run page's job: a new point of its curve (a new attempt starts a new curve).
function extendHistory(id, progress, attempt) {
  const h = state.history;
  if (!h || h.jobId !== id || h.source === "steps") return; // every step is there already
  if (typeof attempt === "number" && attempt !== h.attempt) {
    h.attempt = attempt;
    h.points = [];
  }
  const last = h.points[h.points.length - 1];
  if (last && progress.step <= last.step) return;
  h.points.push({ step: progress.step, loss: progress.loss, irl_loss: progress.irl_loss, sharing_loss: progress.sharing_loss, heldout_nll: progress.heldout_nll ?? null, elapsed_s: progress.elapsed_s });
  h.maxSteps = progress.max_steps || h.maxSteps;
  drawLossCurve($("loss-curve"), h);
}

// ---- loss curve: a small SVG line plot -----------------------------------------------------------

const SERIES = [
  ["loss", "loss", "#2563eb"],
  ["irl_loss", "IRL loss", "#15803d"],
  ["sharing_loss", "sharing loss", "#b45309"],
  ["heldout_nll", "held-out NLL", "#9333ea"],
];
const SVG_NS = "http://www.w3.org/2000/svg";

function svg(tag, attrs = {}, text) {
  const node = document.createElementNS(SVG_NS, tag);
  for (const [name, value] of Object.entries(attrs)) node.setAttribute(name, String(value));
  if (text !== undefined) node.textContent = text;
  return node;
}

// About five round numbers spanning [lo, hi].
function ticks(lo, hi, count = 5) {
  const span = hi - lo || 1;
  const raw = span / count;
  const power = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 5, 10].map((m) => m * power).find((s) => s >= raw);
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(Number(v.toPrecision(12)));
  return out;
}

// What the loss curve's points are, by the history's source.
const CURVE_SOURCES = {
  steps: "(every step of the fit, as the engine computed it)",
  samples: "(per progress sample of the latest attempt; live while it runs)",
};

// Each loss over steps, the kept step marked; the series without values (no hold-out) are left out.
function drawLossCurve(box, history) {
  const points = history.points;
  $("loss-curve-source").textContent = CURVE_SOURCES[history.source] || CURVE_SOURCES.samples;
  if (points.length === 0) {
    fill(box, el("p", { class: "empty" }, "No progress yet: the curve starts with the first step."));
    return;
  }
  const shown = SERIES.filter(([key]) => points.some((p) => Number.isFinite(p[key])));
  let lo = Infinity;
  let hi = -Infinity;
  for (const [key] of shown) {
    for (const p of points) {
      const v = p[key];
      if (Number.isFinite(v)) {
        if (v < lo) lo = v;
        if (v > hi) hi = v;
      }
    }
  }
  const pad = (hi - lo || Math.abs(hi) || 1) * 0.06;
  lo -= pad;
  hi += pad;
  const lastStep = points[points.length - 1].step;
  const xMax = Math.max(history.maxSteps || 0, lastStep, 1);
  const W = Math.max(360, box.clientWidth || 640);
  const H = 240;
  const M = { left: 66, right: 12, top: 10, bottom: 34 };
  const x = (step) => M.left + (step / xMax) * (W - M.left - M.right);
  const y = (v) => M.top + (1 - (v - lo) / (hi - lo)) * (H - M.top - M.bottom);
  const plot = svg("svg", { viewBox: `0 0 ${W} ${H}`, width: W, height: H, role: "img", "aria-label": "loss curve", "data-points": points.length, "data-source": history.source || "samples" });
  // Each axis: a tick mark and its value at round numbers, and the axis's name.
  for (const t of ticks(lo, hi)) {
    plot.append(svg("line", { x1: M.left, x2: W - M.right, y1: y(t), y2: y(t), class: "grid" }));
    plot.append(svg("line", { x1: M.left - 5, x2: M.left, y1: y(t), y2: y(t), class: "axis tick-mark", "data-axis": "y" }));
    plot.append(svg("text", { x: M.left - 8, y: y(t) + 4, "text-anchor": "end", class: "tick", "data-axis": "y" }, fmt(t, 2)));
  }
  for (const t of ticks(0, xMax)) {
    plot.append(svg("line", { x1: x(t), x2: x(t), y1: H - M.bottom, y2: H - M.bottom + 5, class: "axis tick-mark", "data-axis": "x" }));
    plot.append(svg("text", { x: x(t), y: H - M.bottom + 17, "text-anchor": "middle", class: "tick", "data-axis": "x" }, t));
  }
  const middle = M.top + (H - M.top - M.bottom) / 2;
  plot.append(svg("text", { x: 12, y: middle, transform: `rotate(-90 12 ${middle})`, "text-anchor": "middle", class: "axis-label", "data-role": "y-label" }, "loss"));
  plot.append(svg("text", { x: M.left + (W - M.left - M.right) / 2, y: H - 2, "text-anchor": "middle", class: "axis-label", "data-role": "x-label" }, "step"));
  plot.append(svg("line", { x1: M.left, x2: M.left, y1: M.top, y2: H - M.bottom, class: "axis" }));
  plot.append(svg("line", { x1: M.left, x2: W - M.right, y1: H - M.bottom, y2: H - M.bottom, class: "axis" }));
  if (history.bestStep !== null && history.bestStep !== undefined) {
    const bx = x(history.bestStep);
    plot.append(svg("line", { x1: bx, x2: bx, y1: M.top, y2: H - M.bottom, class: "best", "data-role": "best-step" }));
    const right = bx > W / 2; // the label on the side with room
    plot.append(svg("text", { x: right ? bx - 4 : bx + 4, y: M.top + 10, "text-anchor": right ? "end" : "start", class: "tick" }, `kept step ${history.bestStep}`));
  }
  for (const [key, , colour] of shown) {
    plot.append(svg("path", { d: linePath(points, key, x, y), fill: "none", stroke: colour, "stroke-width": 1.6, "data-series": key }));
  }
  const last = points[points.length - 1];
  const legend = el(
    "div",
    { class: "legend" },
    shown.map(([key, label, colour]) => el("span", { "data-series": key }, el("i", { style: { background: colour } }), `${label} ${fmt(last[key])}`)),
  );
  fill(box, plot, legend);
}

// The SVG path of one series. Where points are denser than half a pixel (a curve of every step, up to
// 100,000), each pixel column draws the first, lowest, highest and last value it holds: the same picture
// from a path of at most four points a pixel.
function linePath(points, key, x, y) {
  const parts = [];
  let column = null;
  let seen = [];
  const flush = () => {
    if (!seen.length) return;
    const low = seen.reduce((a, b) => (b[1] < a[1] ? b : a));
    const high = seen.reduce((a, b) => (b[1] > a[1] ? b : a));
    const kept = seen.length <= 4 ? seen : [seen[0], ...(low[0] <= high[0] ? [low, high] : [high, low]), seen[seen.length - 1]];
    for (const [px, v] of kept) parts.push(`${parts.length ? "L" : "M"}${px.toFixed(1)},${y(v).toFixed(1)}`);
    seen = [];
  };
  for (const p of points) {
    const v = p[key];
    if (!Number.isFinite(v)) continue;
    const px = x(p.step);
    const c = Math.round(px * 2);
    if (c !== column) {
      flush();
      column = c;
    }
    seen.push([px, v]);
  }
  flush();
  return parts.join("");
}

// ---- downloads: every format of every reward, the MDP arrays, the recordings' demonstrations ------

// A download fetched with the key and saved under the server's file name (a plain link cannot send the header).
function downloadLink(path, label, title) {
  return el("a", { href: ROOT + path, class: "download", "data-download": path, title: title || label, onclick: (event) => saveDownload(event, path) }, label);
}

async function saveDownload(event, path) {
  event.preventDefault();
  try {
    const response = await api(path);
    const disposition = response.headers.get("content-disposition") || "";
    const name = (disposition.match(/filename="?([^";]+)"?/) || [])[1] || path.split("/").pop().split("?")[0];
    const url = URL.createObjectURL(await response.blob());
    const a = el("a", { href: url, download: name });
    document.body.append(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 10000);
  } catch (error) {
    reportError(error);
  }
}

const MAPS = ["json", "npy", "csv", "png"];
const QUANTITY_FORMATS = { reward: MAPS, value: MAPS, policy: ["json", "npy", "csv"], uncertainty: MAPS, evidence: MAPS };

// The links of one reward: for each quantity it has (the baseline no value or policy; the spread and the evidence
// where its links name them), each format.
function rewardDownloads(reward) {
  const own = reward.kind === "baseline" ? ["reward"] : ["reward", "value", "policy"];
  const quantities = [...own, ...["uncertainty", "evidence"].filter((quantity) => reward.links[quantity])];
  return quantities.map((quantity) =>
    el(
      "span",
      { class: "quantity" },
      `${quantity}: `,
      QUANTITY_FORMATS[quantity]
        .filter((format) => format !== "png" || reward.links.png)
        .map((format) => downloadLink(`/v1/rewards/${encodeURIComponent(reward.reward_id)}?format=${format}&quantity=${quantity}`, format)),
    ),
  );
}

async function renderDownloads(job) {
  const call = state.runCall;
  const box = $("downloads");
  fill(box, loading());
  try {
    const rewards = await getJson(`/v1/jobs/${encodeURIComponent(job.id)}/rewards`);
    if (call !== state.runCall) return;
    const d = state.demonstrators.get(job.demonstrator_id);
    const tasks = d ? d.tasks.filter((t) => job.task_ids.includes(t.id)) : [];
    const mdpIds = [...new Set(tasks.map((t) => t.mdp_id).filter(Boolean))];
    const recordings = d ? d.recordings.filter(isMovement) : []; // standing trials are not cut into demonstrations
    fill(box,
      el(
        "table",
        { class: "readout downloads-table" },
        el(
          "tbody",
          {},
          [rewards.baseline, ...rewards.tasks].map((r) =>
            el("tr", { "data-reward": r.reward_id }, el("th", { class: "row" }, r.kind === "baseline" ? "baseline" : r.task_name || r.task_id), el("td", {}, rewardDownloads(r))),
          ),
          mdpIds.map((id) => el("tr", { "data-mdp": id }, el("th", { class: "row" }, `MDP ${mdpName(id)}`), el("td", {}, downloadLink(`/v1/mdps/${encodeURIComponent(id)}/arrays`, "arrays (.npz)")))),
          recordings.map((r) =>
            el(
              "tr",
              { "data-recording": r.id },
              el("th", { class: "row" }, `recording ${recordingName(r)}`),
              el("td", {}, "demonstrations: ", downloadLink(`/v1/recordings/${encodeURIComponent(r.id)}/demonstrations`, "json"), downloadLink(`/v1/recordings/${encodeURIComponent(r.id)}/demonstrations?format=csv`, "csv")),
            ),
          ),
        ),
      ),
    );
  } catch (error) {
    if (call === state.runCall) fill(box, unavailable(error));
  }
}

// ---- lightbox: a heatmap at full size ------------------------------------------------------------

// The picture (a heatmap, or a map beside one) at its natural size; with ``channels`` ({reward, layout} of a
// layout with several channels) also a button per channel that draws that channel alone, filling the screen.
// Focus moves to its Close button; Escape or Close shut it and return focus to where it was.
function openLightbox(src, title, channels, what = `heatmap of ${title}`) {
  if (!src) return;
  showWholePicture();
  renderChannelButtons(channels, title);
  $("lightbox-img").src = src;
  $("lightbox-img").alt = `${what}, full size`;
  $("lightbox-title").textContent = title;
  $("lightbox-open").href = src;
  if ($("lightbox").hidden) state.lightboxOpener = document.activeElement;
  $("lightbox").hidden = false;
  $("lightbox-close").focus();
}

function closeLightbox() {
  const wasOpen = !$("lightbox").hidden;
  $("lightbox").hidden = true;
  state.lightboxCall += 1;
  $("lightbox-loading").hidden = true;
  $("lightbox-img").removeAttribute("src");
  $("lightbox-title").textContent = "";
  $("lightbox-open").removeAttribute("href");
  fill($("lightbox-channels"));
  fill($("lightbox-channel-title"));
  const opener = state.lightboxOpener;
  state.lightboxOpener = null;
  if (wasOpen && opener && opener.isConnected && typeof opener.focus === "function") opener.focus();
}

// Tab and Shift+Tab stay inside the open lightbox (it covers the page).
function keepFocusInLightbox(event) {
  const focusable = [...$("lightbox").querySelectorAll("button, a[href]")].filter((node) => !node.disabled && node.offsetParent !== null);
  if (!focusable.length) return;
  const first = focusable[0];
  const last = focusable[focusable.length - 1];
  if (event.shiftKey && (document.activeElement === first || !$("lightbox").contains(document.activeElement))) {
    event.preventDefault();
    last.focus();
  } else if (!event.shiftKey && (document.activeElement === last || !$("lightbox").contains(document.activeElement))) {
    event.preventDefault();
    first.focus();
  }
}

// ---- MDPs ----------------------------------------------------------------------------------------

async function loadMdps(generation) {
  const mdps = await getAll("/v1/mdps");
  if (generation !== state.generation) return;
  state.mdps = mdps;
  fill($("mdps"),
    ...(mdps.length
      ? mdps.map((m) =>
          el(
            "div",
            { class: "mdp", "data-mdp": m.id },
            el("span", { class: "dem-name" }, m.name || m.id),
            " ",
            el("span", { class: "meta" }, `${m.n_states} states × ${m.n_actions} actions`),
            " ",
            downloadLink(`/v1/mdps/${encodeURIComponent(m.id)}/arrays`, ".npz"),
            " ",
            deleteButton("mdp", m.id, `MDP ${m.name || m.id}`),
          ),
        )
      : [el("p", { class: "empty" }, "No MDPs yet.")]),
  );
}

function mdpName(id) {
  const m = state.mdps.find((x) => x.id === id);
  return m ? m.name || id : id;
}

// ---- submit a job --------------------------------------------------------------------------------

function renderSubmitForm() {
  const select = $("submit-demonstrator");
  const previous = select.value;
  const withTasks = [...state.demonstrators.values()].filter((d) => d.tasks.length > 0);
  fill(select, ...withTasks.map((d) => el("option", { value: d.id }, d.name)));
  if (withTasks.some((d) => d.id === previous)) select.value = previous;
  $("submit-job").disabled = withTasks.length === 0;
  renderSubmitTasks();
  if (!$("submit-config").firstChild) renderConfigFields();
}

function renderSubmitTasks() {
  const d = state.demonstrators.get($("submit-demonstrator").value);
  fill($("submit-tasks"),
    el("legend", {}, "Tasks"),
    ...(d ? d.tasks : []).map((t) => el("label", {}, el("input", { type: "checkbox", name: "task", value: t.id, checked: true }), ` ${t.name}`)),
  );
}

// One input per JobConfig setting, empty with its default as the placeholder (empty: the default is used).
function renderConfigFields() {
  const props = state.configSchema;
  if (!props) return;
  fill($("submit-config"),
    ...Object.entries(props).map(([name, schema]) => {
      const shown = JSON.stringify(defaultOf(schema));
      const range = settingRange(schema);
      // A choice (an enum, a yes/no setting) is a list to pick from: the default first, then the others.
      const choices = schema.enum || (schema.type === "boolean" ? [true, false] : null);
      const input = choices
        ? el("select", { name }, el("option", { value: "" }, `${schema.default} (default)`), choices.filter((v) => v !== schema.default).map((v) => el("option", { value: JSON.stringify(v) }, String(v))))
        : el("input", {
            name,
            placeholder: isList(schema) && Array.isArray(defaultOf(schema)) ? defaultOf(schema).join(", ") : shown,
            inputmode: schema.type === "number" || schema.type === "integer" ? "decimal" : undefined,
            spellcheck: "false",
          });
      return el("label", { class: "config-field", title: `${schema.description || ""}${range ? ` (${range})` : ""}`, "data-setting": name }, el("span", {}, name, range ? el("small", {}, ` ${range}`) : null), input);
    }),
  );
}

// "≥ 0, < 1": a setting's bounds as the schema states them (inclusive or exclusive).
function settingRange(schema) {
  const bound = (key, sign) => (schema[key] === undefined ? "" : `${sign} ${schema[key] >= 1e6 ? schema[key].toExponential(1) : schema[key]}`);
  return [bound("minimum", "≥"), bound("exclusiveMinimum", ">"), bound("maximum", "≤"), bound("exclusiveMaximum", "<")].filter(Boolean).join(", ");
}

// Whether a setting takes a list (of integers, as `hidden`), maybe or null.
function isList(schema) {
  return schema.type === "array" || (schema.anyOf || []).some((s) => s.type === "array");
}

// The settings typed in: JSON where it parses (numbers, lists, null), else the text as a string; a list
// setting also takes numbers separated by commas or spaces ("8, 8" or "8": [8, 8] or [8]).
function typedConfig() {
  const props = state.configSchema || {};
  const config = {};
  for (const field of $("submit-config").querySelectorAll("input, select")) {
    const text = field.value.trim();
    if (!text) continue;
    let value;
    try {
      value = JSON.parse(text);
    } catch (_) {
      value = text;
    }
    if (props[field.name] && isList(props[field.name]) && !Array.isArray(value) && value !== null) {
      const items = String(text).replace(/^\[|\]$/g, "").split(/[\s,;]+/).filter(Boolean);
      if (items.length && items.every((item) => /^[-+]?\d+(\.\d+)?$/.test(item))) value = items.map(Number);
    }
    config[field.name] = value;
  }
  return config;
}

function submitError(text) {
  $("submit-error").textContent = text;
  $("submit-error").hidden = !text;
}

async function submitJob(event) {
  event.preventDefault();
  const generation = state.generation;
  const tasks = [...$("submit-tasks").querySelectorAll("input[name=task]:checked")].map((i) => i.value);
  if (tasks.length === 0) {
    submitError("Tick at least one task.");
    return;
  }
  submitError("");
  $("submit-job").disabled = true;
  try {
    const job = await getJson("/v1/jobs", {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ demonstrator_id: $("submit-demonstrator").value, task_ids: tasks, config: typedConfig() }),
    });
    if (generation !== state.generation) return;
    turnPage("first");
    await loadJobs(generation);
    showRun(job.id, { scroll: true });
  } catch (error) {
    if (generation !== state.generation) return;
    if (error instanceof ApiError && error.status !== 401) submitError(`${error.status}: ${error.message}`);
    else reportError(error);
  } finally {
    $("submit-job").disabled = false;
  }
}

// ---- delete demonstrators, tasks, MDPs and jobs --------------------------------------------------

const DELETE_PATHS = { demonstrator: "/v1/demonstrators/", task: "/v1/tasks/", mdp: "/v1/mdps/", job: "/v1/jobs/" };

function deleteButton(kind, id, what) {
  return el("button", { type: "button", class: "danger small", "data-action": `delete-${kind}`, title: `Delete ${what}`, onclick: () => deleteResource(kind, id, what) }, "Delete");
}

async function deleteResource(kind, id, what) {
  if (!confirm(`Delete ${what}? This cannot be undone.`)) return;
  const generation = state.generation;
  try {
    await api(DELETE_PATHS[kind] + encodeURIComponent(id), { method: "DELETE" });
    if (generation !== state.generation) return;
    // A demonstrator or task takes its jobs with it: the run page and results shown may be gone.
    if (state.run === id || kind === "demonstrator" || kind === "task") hideRun();
    if (state.selected === id || kind === "demonstrator" || kind === "task") hideResults();
    // The panels of a deleted demonstrator go at once; the others are drawn again below from what is left.
    if (kind === "demonstrator" && state.motion === id) hideMotion();
    if (kind === "demonstrator" && state.sway === id) hideSway();
    await loadDemonstrators(generation);
    await Promise.all([loadJobs(generation), loadMdps(generation)]);
    if (generation !== state.generation) return;
    redrawPanels(); // a motion readout may have lost its job, its partner or its recordings
    showMessage(`Deleted ${what}.`, "info");
  } catch (error) {
    if (generation === state.generation) reportError(error);
  }
}

document.addEventListener("DOMContentLoaded", () => {
  $("filter-status").addEventListener("change", () => turnPage("first"));
  $("filter-demonstrator").addEventListener("change", () => turnPage("first"));
  $("jobs-next").addEventListener("click", () => turnPage("next"));
  $("jobs-prev").addEventListener("click", () => turnPage("prev"));
  $("submit-demonstrator").addEventListener("change", renderSubmitTasks);
  $("submit-form").addEventListener("submit", submitJob);
  $("lightbox-close").addEventListener("click", closeLightbox);
  // A click on the picture or beside it closes (not one on the bar, nor on a channel drawn alone).
  $("lightbox").addEventListener("click", (event) => {
    if (event.target === $("lightbox") || event.target === $("lightbox-img") || event.target.classList.contains("lightbox-body")) closeLightbox();
  });
  document.addEventListener("keydown", (event) => {
    if ($("lightbox").hidden) return;
    if (event.key === "Escape") closeLightbox();
    else if (event.key === "Tab") keepFocusInLightbox(event);
  });
});

// ---- heatmap channels: one channel of a reward at full size, drawn from its values ----------------

// Viridis (matplotlib's default colour map, as the server's heatmaps use) at five stops, interpolated.
const VIRIDIS = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];

function viridis(t) {
  const u = Math.min(1, Math.max(0, t)) * (VIRIDIS.length - 1);
  const i = Math.min(VIRIDIS.length - 2, Math.floor(u));
  const [a, b] = [VIRIDIS[i], VIRIDIS[i + 1]];
  return `rgb(${a.map((c, k) => Math.round(c + (b[k] - c) * (u - i))).join(",")})`;
}

// The layout of the MDP a task is on (from the MDPs listed), or null.
function layoutOfTask(taskId) {
  for (const d of state.demonstrators.values()) {
    const task = d.tasks.find((t) => t.id === taskId);
    if (task) return state.mdps.find((m) => m.id === task.mdp_id)?.layout || null;
  }
  return null;
}

// The name of a layout's channel as the server's heatmaps title their panels: the velocity grid's directions
// when there are eight channels, "channel k" otherwise; "" for a layout of one channel.
const DIRECTION_NAMES = ["right", "forward right", "forward", "forward left", "left", "backward left", "backward", "backward right"];

function channelName(layout, channel) {
  if (layout && layout.channels === 1) return "";
  if (layout && layout.channels === DIRECTION_NAMES.length) return DIRECTION_NAMES[channel] ?? `channel ${channel}`;
  return `channel ${channel}`;
}

function renderChannelButtons(channels, title) {
  const bar = $("lightbox-channels");
  bar.hidden = !channels;
  if (!channels) return fill(bar);
  const pick = (button, draw) => {
    for (const b of bar.querySelectorAll("button")) {
      b.classList.toggle("quiet", b !== button);
      b.setAttribute("aria-pressed", String(b === button));
    }
    Promise.resolve(draw()).catch(reportError);
  };
  const all = el("button", { type: "button", class: "small", "data-channel": "all", "aria-pressed": "true" }, "all channels");
  all.addEventListener("click", () => pick(all, showWholePicture));
  const each = Array.from({ length: channels.layout.channels }, (_, c) => {
    const name = channelName(channels.layout, c);
    const caption = `${title} — ${channels.layout.channels === DIRECTION_NAMES.length ? `moving ${name}` : name}`;
    const button = el("button", { type: "button", class: "small quiet", "data-channel": c, "aria-pressed": "false" }, name);
    button.addEventListener("click", () => pick(button, () => drawChannel(channels.reward, channels.layout, c, caption)));
    return button;
  });
  fill(bar, all, ...each);
}

function showWholePicture() {
  state.lightboxCall += 1;
  $("lightbox-loading").hidden = true;
  $("lightbox-channel").hidden = true;
  $("lightbox-img").hidden = false;
}

// Channel ``channel`` of the reward (state = (channel·height + y)·width + x, y up), coloured on the range of
// all channels so that channels compare, at the largest whole number of pixels per cell the window allows
// (room left for the axes); a loading sign shows while its values come.
async function drawChannel(reward, layout, channel, caption) {
  const call = ++state.lightboxCall;
  $("lightbox-loading").hidden = false;
  let values;
  try {
    ({ values } = await getJson(`/v1/rewards/${encodeURIComponent(reward.reward_id)}?format=json`));
  } finally {
    if (call === state.lightboxCall) $("lightbox-loading").hidden = true;
  }
  if (call !== state.lightboxCall) return;
  const { width, height } = layout;
  const lo = Math.min(...values);
  const hi = Math.max(...values);
  const cell = Math.max(4, Math.floor(Math.min((innerWidth - 90) / width, (innerHeight - 170) / height)));
  const canvas = $("lightbox-canvas");
  canvas.width = width * cell;
  canvas.height = height * cell;
  canvas.dataset.channel = channel;
  const context = canvas.getContext("2d");
  for (let y = 0; y < height; y++) {
    for (let x = 0; x < width; x++) {
      const v = values[(channel * height + y) * width + x];
      context.fillStyle = viridis(hi > lo ? (v - lo) / (hi - lo) : 0.5);
      context.fillRect(x * cell, (height - 1 - y) * cell, cell, cell);
    }
  }
  drawAxisTicks(width, height, cell);
  canvas.setAttribute("aria-label", `${caption}, reward ${fmt(lo)} (purple) to ${fmt(hi)} (yellow), x to the right, y up`);
  fill($("lightbox-channel-title"), el("strong", {}, caption), ` · reward from ${fmt(lo)} (purple) to ${fmt(hi)} (yellow), on the range of all channels`);
  $("lightbox-img").hidden = true;
  $("lightbox-channel").hidden = false;
}

// The cell numbers along the drawn channel's x axis (below it) and y axis (beside it, 0 at the bottom), as
// the server's heatmaps number them; every cell's while they are wide enough, else every 2nd, 5th, 10th, ….
function drawAxisTicks(width, height, cell) {
  const every = [1, 2, 5, 10, 20, 50, 100].find((k) => k * cell >= 22) || 200;
  const tick = (n, size) => el("span", { style: size }, n % every === 0 ? String(n) : "");
  fill($("lightbox-x-ticks"), Array.from({ length: width }, (_, x) => tick(x, { width: `${cell}px` })));
  fill($("lightbox-y-ticks"), Array.from({ length: height }, (_, k) => tick(height - 1 - k, { height: `${cell}px`, lineHeight: `${cell}px` })));
}
