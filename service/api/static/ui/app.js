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
  swayCall: 0, // bumped by each showSway, so an earlier call's late answers never redraw the sway panel
  listTimer: null,
  generation: 0, // bumped when the key changes, so late answers for the old key are dropped
  resultsCall: 0, // bumped by each showResults, so an earlier call's late answers never redraw the results
  motionCall: 0, // the same for showMotion
  comparisonCall: 0, // the same for showComparison
  webhooksCall: 0, // the same for loadWebhooks: an earlier listing never redraws over a later one
  mode: "", // how progress arrives: "stream" or "polling"
  openStreams: 0,
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
  for (const child of children.flat()) {
    if (child === undefined || child === null || child === false) continue;
    node.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return node;
}

function fmt(x, digits = 3) {
  if (x === null || x === undefined || Number.isNaN(x)) return "–";
  const a = Math.abs(x);
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) return x.toExponential(2);
  return x.toFixed(digits);
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

function stopAll() {
  state.generation += 1;
  state.resultsCall += 1;
  state.motionCall += 1;
  state.comparisonCall += 1;
  state.webhooksCall += 1;
  for (const controller of state.watching.values()) controller.abort();
  state.watching.clear();
  clearInterval(state.listTimer);
  state.listTimer = null;
  state.jobs.clear();
  state.rows.clear();
  state.demonstrators.clear();
  state.selected = null;
  state.motion = null;
  $("jobs").replaceChildren();
  $("results").hidden = true;
  $("motion").hidden = true;
  $("webhooks").replaceChildren();
  hideSecret();
  $("webhook-error").hidden = true;
  releaseBlobs();
}

async function loadEverything() {
  const generation = state.generation;
  try {
    await loadDemonstrators(generation);
    await Promise.all([loadJobs(generation), loadWebhooks(generation)]);
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
      return { ...d, tasks, recordings };
    }),
  );
  if (generation !== state.generation) return;
  state.demonstrators = new Map(details.map((d) => [d.id, d]));
  renderDemonstrators();
}

function renderDemonstrators() {
  const box = $("demonstrators");
  if (state.demonstrators.size === 0) {
    box.replaceChildren(el("p", { class: "empty" }, "No demonstrators yet."));
    return;
  }
  box.replaceChildren(
    ...[...state.demonstrators.values()].map((d) =>
      el(
        "div",
        { class: `dem${state.motion === d.id ? " selected" : ""}`, "data-demonstrator": d.id },
        el("div", { class: "dem-name" }, d.name),
        el("div", { class: "id" }, d.id),
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
                .map((r) => `${r.name} (${r.n_samples} samples, ${fmt(r.duration, 1)} s)`)
                .join("; "),
              " ",
              el("button", { class: "small quiet", "data-action": "motion", onclick: () => showMotion(d.id, { scroll: true }) }, "Motion readout"),
              swayButton(d),
            )
          : el("div", { class: "sub" }, "no recordings"),
      ),
    ),
  );
}

function demonstratorName(id) {
  const d = state.demonstrators.get(id);
  return d ? d.name : id;
}

// ---- jobs ----------------------------------------------------------------------------------------

async function loadJobs(generation) {
  const jobs = await getAll("/v1/jobs");
  if (generation !== state.generation) return;
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
  if (previous && previous.status !== "succeeded" && job.status === "succeeded" && state.selected === null) {
    showResults(job.id);
  }
}

function renderJobRow(job) {
  let row = state.rows.get(job.id);
  if (!row) {
    const tr = el("tr", { "data-job": job.id });
    const errorTr = el("tr", { class: "error-row", hidden: true }, el("td", { class: "error", colspan: 6 }));
    row = { tr, errorTr };
    state.rows.set(job.id, row);
    $("jobs").prepend(tr, errorTr);
    $("jobs-empty").hidden = true;
  }
  const p = job.progress;
  const steps = p ? p.max_steps || job.config.max_steps : job.config && job.config.max_steps;
  const fraction = job.status === "succeeded" ? 1 : p && steps ? Math.min(1, p.step / steps) : 0;
  const done = job.status === "succeeded";
  const barText = p ? `step ${p.step} / ${steps}${p.elapsed_s != null ? ` · ${fmt(p.elapsed_s, 1)} s` : ""}` : job.status === "queued" ? "waiting for a worker" : "";
  const created = new Date(job.created_at);
  row.tr.dataset.status = job.status;
  row.tr.className = state.selected === job.id ? "selected" : "";
  row.tr.replaceChildren(
    el("td", {}, el("div", { class: "id", title: job.id }, job.id), el("div", { class: "bar-text" }, created.toLocaleString())),
    el("td", {}, demonstratorName(job.demonstrator_id), el("div", { class: "bar-text" }, `${job.task_ids.length} tasks`)),
    el("td", {}, el("span", { class: `badge ${job.status}`, "data-role": "status" }, job.cancel_requested && !TERMINAL.has(job.status) ? `${job.status} (cancelling)` : job.status)),
    el(
      "td",
      {},
      el("div", { class: `bar${done ? " done" : ""}`, role: "progressbar", "aria-valuemin": 0, "aria-valuemax": 100, "aria-valuenow": Math.round(fraction * 100) }, el("span", { style: { width: `${(fraction * 100).toFixed(1)}%` } })),
      el("div", { class: "bar-text" }, barText),
    ),
    el("td", { class: "num" }, p ? fmt(p.loss) : "–"),
    el(
      "td",
      { class: "actions" },
      !TERMINAL.has(job.status)
        ? el("button", { class: "danger small", "data-action": "cancel", disabled: job.cancel_requested, onclick: () => cancelJob(job.id) }, "Cancel")
        : null,
      job.status === "succeeded"
        ? el("button", { class: "small", "data-action": "results", onclick: () => showResults(job.id) }, "Results")
        : null,
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
  updateJob(job);
  return job;
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
  $("heatmaps").replaceChildren(el("p", { class: "empty" }, "Loading…"));
  $("matrix").replaceChildren();
  $("key-states").replaceChildren();
  try {
    const [rewards, matrix] = await Promise.all([
      getJson(`/v1/jobs/${encodeURIComponent(id)}/rewards`),
      getJson(`/v1/jobs/${encodeURIComponent(id)}/comparison-matrix`),
    ]);
    if (!current()) return;
    renderHeatmaps(rewards, current);
    renderMatrix(matrix);
    const keyStates = await Promise.all(
      rewards.tasks.map((t) => getJson(`/v1/rewards/${encodeURIComponent(t.reward_id)}/key-states?top=5`)),
    );
    if (!current()) return;
    renderKeyStates(rewards.tasks, keyStates);
  } catch (error) {
    if (current()) reportError(error);
  }
}

function renderHeatmaps(rewards, current) {
  const cards = [rewards.baseline, ...rewards.tasks].map((reward) => {
    const title = reward.kind === "baseline" ? "baseline (shared)" : reward.task_name || reward.task_id;
    const s = reward.summary;
    const picture = reward.links.png
      ? el("img", { alt: `heatmap of ${title}`, "data-reward": reward.reward_id })
      : el("div", { class: "nopic" }, "No layout on this MDP, so no heatmap (download JSON or CSV).");
    // Beside the reward, how much the ensemble's members disagree on it per state: where it is least sure.
    const spread = reward.links.uncertainty_png
      ? el(
          "div",
          { class: "uncertainty", "data-role": "uncertainty" },
          el("img", { alt: `uncertainty of ${title}`, "data-uncertainty": reward.reward_id }),
          el("span", { class: "stats" }, "spread across the ensemble's members (higher: less sure)"),
        )
      : null;
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
      spread,
    );
    if (reward.links.png) loadImage(picture, "results", current, reward.links.png);
    if (spread) loadImage(spread.querySelector("img"), "results", current, reward.links.uncertainty_png);
    return card;
  });
  $("heatmaps").replaceChildren(...cards);
}

// Fetch a picture with the key and show it from a blob: URL, kept with the view's others until released.
async function loadImage(img, view, current, path, options) {
  try {
    const blob = await (await api(path, options)).blob();
    if (!current()) return;
    const url = URL.createObjectURL(blob);
    state.blobUrls[view].push(url);
    img.src = url;
  } catch (error) {
    if (current()) img.replaceWith(el("div", { class: "nopic" }, `${img.alt}: unavailable (${error.message})`));
  }
}

// Diverging colours for a correlation in [-1, 1]: red below 0, blue above.
function correlationColour(r) {
  const a = Math.min(1, Math.abs(r));
  return r >= 0 ? `rgba(37, 99, 235, ${0.08 + 0.8 * a})` : `rgba(220, 38, 38, ${0.08 + 0.8 * a})`;
}

function renderMatrix(m) {
  const head = el("tr", {}, el("th", {}), m.labels.map((label) => el("th", { title: label }, label)));
  const rows = m.matrix.map((row, i) =>
    el(
      "tr",
      {},
      el("th", { class: "row", title: m.labels[i] }, m.labels[i]),
      row.map((r) =>
        el("td", { class: "num", style: { background: correlationColour(r), color: Math.abs(r) > 0.55 ? "#fff" : "#1f2933" } }, fmt(r, 2)),
      ),
    ),
  );
  $("matrix").replaceChildren(el("table", { class: "matrix" }, el("thead", {}, head), el("tbody", {}, rows)));
}

function renderKeyStates(tasks, all) {
  const tables = all.map((ks, i) =>
    el(
      "table",
      { "data-task": ks.task_id },
      el("caption", {}, tasks[i].task_name || ks.task_id),
      el("thead", {}, el("tr", {}, ["#", "state", "x, y", "reward", "baseline", "diff."].map((h) => el("th", {}, h)))),
      el(
        "tbody",
        {},
        ks.states.map((s) =>
          el(
            "tr",
            {},
            el("td", {}, s.rank),
            el("td", {}, s.state),
            el("td", {}, s.x === null ? "–" : `${s.x}, ${s.y}${s.channel ? ` (${s.channel})` : ""}`),
            el("td", { class: "num" }, fmt(s.reward, 2)),
            el("td", { class: "num" }, fmt(s.baseline, 2)),
            el("td", { class: `num ${s.difference >= 0 ? "pos" : "neg"}` }, fmt(s.difference, 2)),
          ),
        ),
      ),
    ),
  );
  $("key-states").replaceChildren(...(tables.length ? tables : [el("p", { class: "empty" }, "No tasks.")]));
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
  return el("p", { class: "empty" }, "Loading…");
}

function unavailable(error) {
  return el("p", { class: "empty" }, `Unavailable: ${error.message}`);
}

// Whether a 95 % interval leaves out 0 (null bounds: one repetition, no interval).
function clearOfZero(v) {
  return v.low !== null && v.high !== null && (v.low > 0 || v.high < 0);
}

// A mean with its 95 % interval below it (none with a single repetition).
function intervalCell(v, className = "") {
  return el(
    "td",
    { class: `num ${className}` },
    fmt(v.mean),
    el("div", { class: "ci" }, v.low === null || v.high === null ? "" : `[${fmt(v.low)}, ${fmt(v.high)}]`),
  );
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
  $("kinematics").replaceChildren(loading());
  $("learned").replaceChildren();
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
    box.replaceChildren(loading());
    await renderLearned(summary.learned, current);
  } catch (error) {
    if (!current()) return;
    box.replaceChildren(unavailable(error));
    reportError(error);
  }
}

function renderKinematics(summary) {
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
        el("tr", { "data-direction": d.direction }, el("th", { class: "row" }, d.direction), el("td", { class: "num" }, d.n_segments), DESCRIPTORS.map(([key]) => intervalCell(d[key]))),
      ),
    ),
  );
  $("kinematics").replaceChildren(table, el("p", { class: "units" }, unitsNote(summary.units)));
}

// Table I of the paper, as the API reads it out: per direction task of the job, the states its
// demonstrations visit, the ring-centred baseline there, the task reward's r with the baseline there, and
// (where the tasks carry a true reward) the task reward's r with it from the job's rewards listing.
async function renderLearned(learned, current) {
  if (!learned) {
    $("learned").replaceChildren(el("p", { class: "empty" }, "No job on this demonstrator has succeeded yet: the readout of its learned rewards shows here once one has."));
    return;
  }
  const rewards = await getJson(`/v1/jobs/${encodeURIComponent(learned.job_id)}/rewards`);
  if (!current()) return;
  const truth = new Map(rewards.tasks.map((t) => [t.task_id, t.truth_pearson]));
  const withTruth = learned.directions.some((d) => truth.get(d.task_id) !== null && truth.get(d.task_id) !== undefined);
  const verdict = renderAgreement(learned.agreement);
  const preference = learned.agreement.verdict === "agrees" ? "baseline, ring-centred" : "baseline, ring-centred (not a preference)";
  const heads = ["direction", "visited states", preference, "r(task, baseline)"];
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
              withTruth ? el("td", { class: "num" }, fmt(truth.get(d.task_id), 2)) : null,
            ),
          ),
        ),
      )
    : el("p", { class: "empty" }, "The job has no direction tasks on a velocity grid, so there is nothing to read out per direction.");
  $("learned").replaceChildren(
    el(
      "div",
      { class: "learned-job" },
      "job ",
      el("span", { class: "id" }, learned.job_id),
      " ",
      el("button", { class: "small quiet", "data-action": "results", onclick: () => showResults(learned.job_id, { scroll: true }) }, "Heatmaps"),
    ),
    verdict,
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
    agreement.detail,
  );
}

// The other demonstrators with recordings, as the sessions to compare with; the choice is kept if it still fits.
function renderPartners(id) {
  $("compare-label").textContent = `${demonstratorName(id)} (a), against b =`;
  const select = $("compare-with");
  const previous = select.value;
  const others = [...state.demonstrators.values()].filter((d) => d.id !== id && d.recordings.length > 0);
  select.replaceChildren(...others.map((d) => el("option", { value: d.id }, d.name)));
  if (others.some((d) => d.id === previous)) select.value = previous;
  select.disabled = others.length === 0;
}

async function showComparison() {
  const call = ++state.comparisonCall;
  const current = () => call === state.comparisonCall;
  releaseBlobs("comparison");
  const a = state.motion;
  const b = $("compare-with").value;
  const box = $("comparison");
  if (!a || !b) {
    box.replaceChildren(el("p", { class: "empty" }, "Upload recordings for another demonstrator (another session) to compare with."));
    return;
  }
  box.dataset.b = b;
  box.replaceChildren(loading());
  const options = { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify({ a, b }) };
  try {
    const comparison = await getJson("/v1/motion-comparisons", options);
    if (!current()) return;
    const img = el("img", { alt: `Comparison figure of ${comparison.b.name} and ${comparison.a.name}` });
    box.replaceChildren(el("figure", { class: "comparison-figure" }, img), renderDifferences(comparison));
    loadImage(img, "comparison", current, comparison.links.png, options);
  } catch (error) {
    if (!current()) return;
    box.replaceChildren(unavailable(error));
    reportError(error);
  }
}

function renderDifferences(c) {
  return el(
    "table",
    { class: "readout differences" },
    el("caption", {}, `${c.b.name} − ${c.a.name} (b − a) per direction; coloured where the 95 % interval leaves out 0`),
    el(
      "thead",
      {},
      el("tr", {}, el("th", {}, "direction"), el("th", { title: "movements of a, of b" }, "n a, b"), DESCRIPTORS.map(([key, label]) => el("th", { title: c.units[key] }, `Δ ${label}`))),
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
            return intervalCell(v, clearOfZero(v) ? (v.mean > 0 ? "pos clear" : "neg clear") : "");
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
  $("webhooks").replaceChildren(
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
  box.replaceChildren(
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
  box.replaceChildren();
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
    const selected = state.selected;
    const motion = state.motion;
    loadEverything().then(() => {
      if (selected && state.jobs.has(selected)) showResults(selected);
      if (motion && state.demonstrators.has(motion)) showMotion(motion);
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

// A "Sway" button for a demonstrator with standing trials (none otherwise).
function swayButton(d) {
  if (!d.recordings.some((r) => r.protocol === "standing")) return null;
  return el("button", { class: "small quiet", "data-action": "sway", onclick: () => showSway(d.id, { scroll: true }) }, "Sway");
}

// The sway panel of a demonstrator: one trial's measures and COP picture, and its trials compared by label.
async function showSway(id, { scroll = false } = {}) {
  const d = state.demonstrators.get(id);
  const trials = d ? d.recordings.filter((r) => r.protocol === "standing") : [];
  const section = $("sway");
  section.hidden = false;
  section.dataset.demonstrator = id;
  $("sway-title").textContent = `Quiet standing of ${demonstratorName(id)}`;
  $("sway-meta").textContent = `${trials.length} standing trial${trials.length === 1 ? "" : "s"}`;
  const select = $("sway-recording");
  select.replaceChildren(
    ...trials.map((r) => el("option", { value: r.id }, `${r.name || r.id}${labelsText(r.metadata)}`)),
  );
  select.onchange = () => showSwayTrial(select.value);
  if (scroll) section.scrollIntoView({ block: "start" });
  if (trials.length) showSwayTrial(trials[0].id);
  await showSwayGroups(id, trials);
}

function labelsText(metadata) {
  const entries = Object.entries(metadata || {});
  return entries.length ? ` (${entries.map(([k, v]) => `${k}: ${v}`).join(", ")})` : "";
}

async function showSwayTrial(recordingId) {
  const call = ++state.swayCall;
  const current = () => call === state.swayCall;
  releaseBlobs("sway");
  $("sway-measures").replaceChildren(loading());
  const img = el("img", { alt: "COP path with its 95 % ellipse", "data-recording": recordingId });
  $("sway-picture").replaceChildren(img);
  try {
    const sway = await getJson(`/v1/recordings/${encodeURIComponent(recordingId)}/sway`);
    if (!current()) return;
    $("sway-measures").replaceChildren(
      el(
        "table",
        { class: "readout sway-measures" },
        el("tbody", {}, SWAY_MEASURES.map(([key, label, kind]) =>
          el("tr", { "data-measure": key }, el("th", {}, label), el("td", { class: "num" }, fmt(sway.descriptors[key])), el("td", { class: "meta" }, swayUnit(kind, sway.units))),
        )),
      ),
      el("p", { class: "sub" }, `${sway.n_samples} samples at ${fmt(sway.rate_hz, 4)} Hz over ${fmt(sway.duration_s, 3)} s`),
    );
    loadImage(img, "sway", current, `/v1/recordings/${encodeURIComponent(recordingId)}/sway?format=png`);
  } catch (error) {
    if (!current()) return;
    $("sway-measures").replaceChildren(unavailable(error));
  }
}

// Trials grouped by `vision` when they carry it, else by their first label; the Romberg quotient for vision.
async function showSwayGroups(id, trials) {
  const box = $("sway-groups");
  const labels = [...new Set(trials.flatMap((r) => Object.keys(r.metadata || {})))];
  const by = labels.includes("vision") ? "vision" : labels[0];
  if (!by) {
    box.replaceChildren(el("p", { class: "empty" }, "Label the trials (metadata such as {\"vision\": \"closed\"}) to compare conditions."));
    return;
  }
  box.replaceChildren(loading());
  try {
    const summary = await getJson(`/v1/demonstrators/${encodeURIComponent(id)}/sway-summary?by=${encodeURIComponent(by)}`);
    const shown = ["area95", "mean_velocity", "mean_frequency"];
    const cell = (v) => el("td", { class: "num" }, fmt(v.value), el("div", { class: "ci" }, v.low === null || v.high === null ? "" : `[${fmt(v.low)}, ${fmt(v.high)}]`));
    const rows = summary.groups.map((g) => el("tr", { "data-group": g.label }, el("th", {}, `${by}: ${g.label} (${g.n})`), ...shown.map((m) => cell(g.measures[m]))));
    if (summary.romberg) rows.push(el("tr", { "data-group": "romberg" }, el("th", {}, "Romberg quotient (closed / open)"), ...shown.map((m) => cell(summary.romberg[m]))));
    box.replaceChildren(
      el(
        "table",
        { class: "readout sway-groups" },
        el("thead", {}, el("tr", {}, el("th", {}, ""), ...shown.map((m) => el("th", {}, SWAY_MEASURES.find(([k]) => k === m)[1])))),
        el("tbody", {}, rows),
      ),
    );
  } catch (error) {
    box.replaceChildren(unavailable(error));
  }
}
