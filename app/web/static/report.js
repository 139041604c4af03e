// The report page's script: plain JavaScript, no build and nothing loaded from elsewhere.
// It calls the service's JSON API with fetch() (sending X-API-Key when the user typed one) and shows
// the server-rendered PNG figures, fetched the same way so that they carry the key too.
"use strict";

(() => {
  const API = document.body.dataset.api || "/v1";
  const KEY_STORAGE = "backlash-api-key";
  const POLL_MS = 500;
  const $ = (id) => document.getElementById(id);

  // -- the API ------------------------------------------------------------------------

  function apiKey() {
    return sessionStorage.getItem(KEY_STORAGE) || "";
  }

  function headers(extra) {
    const h = Object.assign({}, extra || {});
    const key = apiKey();
    if (key) h["X-API-Key"] = key;
    return h;
  }

  // An error answer of the API: its status, the "error" name (e.g. NotFoundError) and the "detail" sentence.
  class ApiError extends Error {
    constructor(status, detail, kind) {
      super(detail);
      this.status = status;
      this.kind = kind || "";
    }
  }

  // The service did not answer at all (down, or the connection lost).
  class NetworkError extends Error {}

  // "detail" of the service's error answers: a sentence, or FastAPI's list of field errors.
  function describeError(body, status) {
    const detail = body && body.detail;
    if (typeof detail === "string") return detail;
    if (Array.isArray(detail)) {
      return detail.map((e) => `${(e.loc || []).join(".")}: ${e.msg}`).join("; ");
    }
    return `HTTP ${status}`;
  }

  async function request(path, init) {
    const options = Object.assign({}, init || {});
    options.headers = headers(options.headers);
    let response;
    try {
      response = await fetch(API + path, options);
    } catch (e) {
      throw new NetworkError(
        `The service did not answer (${e.message}): check that it is running and that this computer reaches it, then try again.`,
      );
    }
    if (!response.ok) {
      let body = null;
      try {
        body = await response.json();
      } catch (_) {
        body = null;
      }
      if (response.status === 401) askForKey();
      throw new ApiError(response.status, describeError(body, response.status), body && body.error);
    }
    return response;
  }

  async function getJSON(path) {
    return (await request(path)).json();
  }

  // Show a PNG of the API in an <img>: fetched with the key, then shown from a blob URL.
  // A link around the <img> (if any) opens the figure full size in a new tab.
  async function showImage(img, path) {
    const blob = await (await request(path)).blob();
    if (img.dataset.objectUrl) URL.revokeObjectURL(img.dataset.objectUrl);
    const url = URL.createObjectURL(blob);
    img.dataset.objectUrl = url;
    await new Promise((resolve, reject) => {
      img.onload = resolve;
      img.onerror = () => reject(new Error(`the figure ${path} could not be shown`));
      img.src = url;
    });
    const link = img.closest("a.full-size");
    if (link) link.href = url;
  }

  const KEY_NEEDED = 'The service needs its API key: type it under "API key" at the top of the page and click "Use key".';

  function askForKey() {
    const form = $("key-form");
    form.hidden = false;
    $("api-key").focus();
    showError(KEY_NEEDED, "API key needed");
  }

  // -- errors and warnings, at the top of the page -----------------------------------------
  // Every failure and every warning of an answer goes to #alerts (right under the header), which is scrolled
  // into view; the next action the user starts clears it. The API's messages say what to fix in HTTP terms
  // (routes, body fields); the page says it in its own: the buttons and fields to use.

  // The page's fields for the API's names (in validation messages, "query sample_interval: ...").
  const FIELDS = {
    sample_interval: "CSV: sample interval",
    event_index: "CSV: event index",
    units: "CSV: units",
    measured_at: "Measured at",
    asset: "Drive (asset)",
    channel: "from channel",
    pattern_set: "with pattern set",
    limit: "Width limit",
  };
  const ROUTE = /\b(GET|POST|PUT|PATCH|DELETE) \/v1\//;
  const NO_SET_HELP = 'click "Diagnose" instead: its report gives the backlash width without a pattern set';

  // The API's sentence without its clauses that name HTTP routes, and with the page's names of the fields.
  function pageTerms(detail) {
    const kept = String(detail).split(/;\s+/).filter((part) => !ROUTE.test(part));
    const text = (kept.length ? kept : [String(detail)]).join("; ");
    return text.replace(/\bquery (\w+)/g, (all, name) => (FIELDS[name] ? `"${FIELDS[name]}"` : all));
  }

  // What went wrong and what to do, in the page's terms, for an error of the page's action.
  function pageMessage(e) {
    if (!(e instanceof ApiError)) return e.message;
    const d = e.message;
    let m;
    if (e.status === 401) return KEY_NEEDED;
    if ((m = /^no pattern set for channel '([^']+)'/.exec(d))) {
      const c = /"c": ([0-9.eE+-]+)/.exec(d);
      const listed = $("pattern-set").length > 1; // beside "(the stored set nearest the record's c)"
      return (
        `No pattern set for channel ${m[1]} is stored that the service would choose by itself (one trained without ` +
        `effects on the paper's J1 grid). ${listed ? 'Pick one of the stored sets under "with pattern set", or ' : ""}` +
        `${listed ? NO_SET_HELP : NO_SET_HELP.replace(/^c/, "C")}. A pattern set is trained by the service's operator ` +
        `(backlash train --channel ${m[1]}${c ? ` --c ${c[1]}` : ""}).`
      );
    }
    if (/^no pattern set with id/.test(d)) {
      return 'The pattern set picked under "with pattern set" is no longer stored; the list is refreshed: pick another one, or "(the stored set nearest the record\'s c)".';
    }
    if ((m = /was trained on channel '([^']+)', not '([^']+)'/.exec(d))) {
      return `The pattern set picked under "with pattern set" was trained on channel ${m[1]}, not ${m[2]}: choose ${m[1]} under "from channel", or pick a set of channel ${m[2]}.`;
    }
    if (/^the nearest stored set/.test(d)) {
      return `${pageTerms(d)}. Pick that set (or another) under "with pattern set" to use it anyway, or ${NO_SET_HELP}.`;
    }
    if (/^pattern set .* model version/.test(d)) {
      return `${pageTerms(d)}: pick another set under "with pattern set", or ${NO_SET_HELP}.`;
    }
    if (/^no record with id/.test(d)) {
      return 'The stored record picked is no longer stored; the list is refreshed: pick another one, or upload a file.';
    }
    if ((m = /^no diagnosis with id '([^']*)'/.exec(d))) {
      return `Diagnosis ${m[1]} is not stored (an old link, or it was deleted): upload a record and click "Diagnose".`;
    }
    if ((m = /^no identification or diagnosis of asset '([^']*)'/.exec(d))) {
      return `Drive ${m[1]} has no history yet: name it under "Drive (asset)" when you diagnose or identify one of its records, and its history starts.`;
    }
    if (e.status >= 500) {
      return `The service failed (HTTP ${e.status}: ${pageTerms(d)}). Try again; if it fails again, tell the service's operator.`;
    }
    return pageTerms(d);
  }

  function alertBox(kind, id, title) {
    const box = el("div", null, { class: `alert ${kind}`, id });
    if (kind === "error") box.setAttribute("role", "alert");
    box.appendChild(el("p", title, { class: "alert-title" }));
    return box;
  }

  function reveal() {
    $("alerts").scrollIntoView({ block: "nearest" });
  }

  // A new action starts with a clean slate: the errors and warnings of the previous one go.
  function clearAlerts() {
    $("alerts").replaceChildren();
  }

  function showError(text, title) {
    const area = $("alerts");
    const old = $("alert-error");
    if (old) old.remove();
    const box = alertBox("error", "alert-error", title || "Error");
    box.appendChild(el("p", text, { class: "alert-text" }));
    area.prepend(box);
    reveal();
  }

  // An action failed: its error at the top, titled with what failed (the status line under the form is cleared).
  function fail(e, title) {
    say("");
    showError(pageMessage(e), e instanceof ApiError && e.status === 401 ? "API key needed" : title);
  }

  // What an answer says to check before acting on it (its "warnings": code, message, channel).
  function showWarnings(warnings, id, what) {
    const old = $(id);
    if (old) old.remove();
    if (!warnings || !warnings.length) return;
    const n = warnings.length;
    const box = alertBox("warning", id, `Check before acting on ${what} (${n} warning${n > 1 ? "s" : ""}):`);
    const list = el("ul");
    for (const w of warnings) list.appendChild(el("li", w.message, w.code ? { "data-code": w.code } : {}));
    box.appendChild(list);
    $("alerts").appendChild(box);
    reveal();
  }

  // -- formatting ---------------------------------------------------------------------

  function num(x, digits) {
    if (x === null || x === undefined || Number.isNaN(x)) return "–";
    if (!Number.isFinite(x)) return x > 0 ? "∞" : "−∞";
    const d = digits || 3;
    const a = Math.abs(x);
    if (a !== 0 && (a >= 1e6 || a < 1e-3)) return x.toExponential(d - 1);
    return Number(x.toPrecision(d)).toString();
  }

  function pct(x) {
    if (x === null || x === undefined) return "–";
    return `${num(100 * x, 3)} %`;
  }

  function mm(metres, digits) {
    if (metres === null || metres === undefined) return "–";
    return num(1000 * metres, digits || 3);
  }

  function words(name) {
    return name ? String(name).replace(/_/g, " ") : "";
  }

  function valueText(value, uncertainty, unit) {
    if (value === null || value === undefined) return "–";
    let s = num(value, 4);
    if (uncertainty !== null && uncertainty !== undefined && Number.isFinite(uncertainty)) {
      s += ` ± ${num(uncertainty, 2)}`;
    }
    if (unit) s += ` ${unit}`;
    return s;
  }

  function dateText(iso) {
    if (!iso) return "–";
    const d = new Date(iso);
    return Number.isNaN(d.getTime()) ? String(iso) : d.toISOString().replace("T", " ").replace(/:\d\d\.\d+Z$|:\d\dZ$/, " UTC");
  }

  function el(tag, text, attrs) {
    const node = document.createElement(tag);
    if (text !== undefined && text !== null) node.textContent = text;
    for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, v);
    return node;
  }

  function row(cells, header) {
    const tr = document.createElement("tr");
    cells.forEach((c, i) => {
      const cell = el(i === 0 && header ? "th" : "td", c);
      if (i === 0 && header) cell.setAttribute("scope", "row");
      tr.appendChild(cell);
    });
    return tr;
  }

  function say(text, kind) {
    const m = $("message");
    m.textContent = text || "";
    m.className = `message ${kind || ""}`;
  }

  // -- the record: an uploaded file or a stored record ---------------------------------

  async function readFile(file) {
    const text = await file.text();
    const trimmed = text.trimStart();
    const isJson = /\.json$/i.test(file.name) || trimmed.startsWith("{");
    if (!isJson) return { kind: "csv", text, name: file.name };
    let obj;
    try {
      obj = JSON.parse(text);
    } catch (e) {
      throw new Error(`${file.name} is not valid JSON: ${e.message}`);
    }
    return { kind: "json", obj, name: file.name };
  }

  // The record the form points at: a stored record (by id) or the uploaded file.
  async function currentRecord() {
    const select = $("stored-record");
    if (select.value) {
      const option = select.selectedOptions[0];
      return { stored: select.value, name: option.textContent, plant: option.dataset.plant };
    }
    const file = $("record-file").files[0];
    if (!file) throw new Error("Choose a record file (CSV or JSON) or pick a stored record first.");
    return readFile(file);
  }

  // A stored record's body as it was sent (JSON, or CSV text with its query parameters).
  async function storedBody(record) {
    const id = encodeURIComponent(record.stored);
    const meta = await getJSON(`/records/${id}`);
    const response = await request(`/records/${id}/body`);
    if (meta.media === "csv") {
      return { kind: "csv", text: await response.text(), params: meta.params || {}, name: record.name, stored: true };
    }
    return { kind: "json", obj: await response.json(), plant: meta.plant, name: record.name, stored: true };
  }

  function formValue(id) {
    return $(id).value.trim();
  }

  function isRequestBody(obj) {
    return obj && typeof obj === "object" && !Array.isArray(obj) && "record" in obj;
  }

  // The record object and its plant, from a record or a whole request body.
  function recordAndPlant(record) {
    const obj = record.obj;
    if (isRequestBody(obj)) return [obj.record, obj.plant || record.plant || formValue("plant")];
    return [obj, record.plant || formValue("plant")];
  }

  // The drive and the instant the form gives, put into the record object (an upload only: a stored
  // record keeps its own).
  function withAsset(record, obj) {
    const out = Object.assign({}, obj);
    if (record.stored) return out;
    if (formValue("asset")) out.asset = formValue("asset");
    if (formValue("measured-at")) out.measured_at = formValue("measured-at");
    return out;
  }

  // JSON body of POST /diagnoses: a whole request body as it is, or {"record": ...} with its plant.
  function diagnoseBody(record) {
    const [obj, plant] = recordAndPlant(record);
    const body = isRequestBody(record.obj) ? Object.assign({}, record.obj) : {};
    body.record = withAsset(record, obj);
    if (plant && plant !== "backlash_drive") body.plant = plant;
    return body;
  }

  // JSON body of POST /identify: the record, the channel and the continuous width (BRFD: the plant's form).
  function identifyBody(record, channel, continuous) {
    const [obj, plant] = recordAndPlant(record);
    const rec = withAsset(record, obj);
    if (plant === "brfd" || plant === "emps") return { plant, record: rec };
    return { record: rec, channel, continuous };
  }

  // Query parameters that complete a CSV record: the stored ones, or the form's.
  function csvParams(record, extra) {
    const p = new URLSearchParams();
    if (record.params) {
      const given = Object.assign({}, record.params, record.params.conditions || {});
      delete given.conditions;
      for (const [k, v] of Object.entries(given)) if (v !== null && v !== undefined) p.set(k, String(v));
    } else if (isUploadedPlant(formValue("plant"))) {
      // an uploaded plant's CSV: the plant, and the drive's name and instant; its units are in its header
      const pairs = [["plant", formValue("plant")], ["asset", formValue("asset")], ["measured_at", formValue("measured-at")]];
      for (const [k, v] of pairs) if (v) p.set(k, v);
    } else {
      const pairs = [
        ["asset", formValue("asset")],
        ["measured_at", formValue("measured-at")],
        ["sample_interval", formValue("sample-interval")],
        ["event_index", formValue("event-index")],
        ["units", formValue("units")],
      ];
      for (const [k, v] of pairs) if (v) p.set(k, v);
      for (const pair of formValue("conditions").split(/[\s,;]+/).filter(Boolean)) {
        const [k, v] = pair.split("=");
        if (!k || v === undefined) throw new Error(`known conditions: write NAME=VALUE pairs, not "${pair}"`);
        p.set(k.trim(), v.trim());
      }
    }
    for (const [k, v] of Object.entries(extra || {})) p.set(k, String(v));
    const q = p.toString();
    return q ? `?${q}` : "";
  }

  function post(path, body, contentType) {
    return request(path, { method: "POST", headers: { "Content-Type": contentType }, body });
  }

  async function submitDiagnosis(record) {
    if (record.stored) {
      return (await request(`/records/${encodeURIComponent(record.stored)}/diagnoses`, { method: "POST" })).json();
    }
    if (record.kind === "csv") return (await post(`/diagnoses${csvParams(record)}`, record.text, "text/csv")).json();
    return (await post("/diagnoses", JSON.stringify(diagnoseBody(record)), "application/json")).json();
  }

  async function submitIdentification(record, channel, continuous) {
    const r = record.stored ? await storedBody(record) : record;
    const patternSet = formValue("pattern-set");
    const chosen = patternSet ? { pattern_set: patternSet } : {};
    if (r.kind === "csv") {
      const query = csvParams(r, Object.assign({ channel, continuous }, chosen));
      return (await post(`/identify${query}`, r.text, "text/csv")).json();
    }
    const body = identifyBody(r, channel, continuous);
    if (body.channel) Object.assign(body, chosen);
    return (await post("/identify", JSON.stringify(body), "application/json")).json();
  }

  async function loadRecords() {
    const select = $("stored-record");
    const keep = select.value;
    const { items } = await getJSON("/records");
    select.length = 1;
    for (const r of items) {
      const label = [r.name || `record ${r.id.slice(0, 8)}`, r.asset, r.measured_at ? dateText(r.measured_at) : null, r.plant]
        .filter(Boolean)
        .join(" · ");
      const option = el("option", label, { value: r.id });
      option.dataset.plant = r.plant || "";
      if (r.asset) option.dataset.asset = r.asset;
      select.appendChild(option);
    }
    select.value = keep;
  }

  async function loadPatternSets() {
    const select = $("pattern-set");
    const keep = select.value;
    const answer = await getJSON("/pattern-sets");
    select.length = 1;
    for (const p of answer.data || answer.items || []) {
      const label = `${p.channel}, c = ${num(p.c)} pu, ${p.kind} (${p.id.slice(0, 8)})`;
      select.appendChild(el("option", label, { value: p.id }));
    }
    select.value = keep;
  }

  // The plants users uploaded as FMUs (GET /plants), added to the plant choice after the built-in ones.
  async function loadPlants() {
    const select = $("plant");
    const keep = select.value;
    const { items } = await getJSON("/plants");
    for (const option of [...select.options]) if (option.dataset.uploaded) option.remove();
    for (const p of items) {
      const option = el("option", `${p.name} (your FMU, ${p.id})`, { value: p.id });
      option.dataset.uploaded = "true";
      select.appendChild(option);
    }
    select.value = [...select.options].some((o) => o.value === keep) ? keep : select.options[0].value;
  }

  // An uploaded plant's id (fmu- and 16 hex digits): its CSV states its own units and time.
  function isUploadedPlant(plant) {
    return /^fmu-[0-9a-f]{16}$/.test(plant || "");
  }

  async function loadAssets() {
    const { items } = await getJSON("/assets");
    const list = $("asset-names");
    list.replaceChildren(...items.map((a) => el("option", null, { value: a.asset })));
  }

  // -- the diagnosis job ---------------------------------------------------------------

  let currentJob = null;

  function setBusy(busy) {
    $("diagnose-button").disabled = busy;
    $("identify-button").disabled = busy;
  }

  function showProgress(job) {
    $("job-section").hidden = false;
    const bar = $("job-progress");
    bar.value = job.progress || 0;
    bar.textContent = pct(job.progress || 0);
    const stage = job.stage && job.stage !== job.state ? `: ${job.stage}` : "";
    $("job-stage").textContent = `${job.state} (${pct(job.progress || 0)})${stage}`;
    $("cancel-button").hidden = !["queued", "running"].includes(job.state);
  }

  async function waitForJob(jobId) {
    for (;;) {
      const job = await getJSON(`/jobs/${encodeURIComponent(jobId)}`);
      showProgress(job);
      if (!["queued", "running"].includes(job.state)) return job;
      await new Promise((r) => setTimeout(r, POLL_MS));
    }
  }

  async function diagnose(event) {
    event.preventDefault();
    clearAlerts();
    setBusy(true);
    say("Sending the record…");
    $("report-section").hidden = true;
    try {
      const record = await currentRecord();
      const accepted = await submitDiagnosis(record);
      currentJob = accepted.job_id;
      history.replaceState(null, "", `?diagnosis=${encodeURIComponent(accepted.diagnosis_id)}`);
      say(`Diagnosing ${record.name || "the record"} (job ${accepted.job_id})…`);
      const job = await waitForJob(accepted.job_id);
      if (job.state !== "done") {
        say("");
        showError(`The diagnosis job ${job.state}${job.error ? `: ${pageTerms(job.error)}` : ""}.`, "The diagnosis stopped");
        return;
      }
      await showDiagnosis(accepted.diagnosis_id);
      say("Diagnosis done.", "ok");
      loadRecords().catch(() => {});
    } catch (e) {
      fail(e, "The record was not diagnosed");
      if (e instanceof ApiError && /^no record with id/.test(e.message)) loadRecords().catch(() => {});
    } finally {
      currentJob = null;
      setBusy(false);
    }
  }

  async function cancel() {
    if (!currentJob) return;
    try {
      await request(`/jobs/${encodeURIComponent(currentJob)}/cancel`, { method: "POST" });
    } catch (e) {
      showError(pageMessage(e), "The job was not cancelled");
    }
  }

  // -- the report ----------------------------------------------------------------------

  const FIGURES = {
    residual_map_before: [
      "Residual map before: the record minus the calibrated nominal model, per channel, wavelet level and time window, coloured by energy over the noise",
      "Residual map of the nominal model (before)",
    ],
    residual_map_after: [
      "Residual map after: what is left once the named effects are fitted, per channel, wavelet level and time window",
      "Residual map with the named effects (after)",
    ],
    overlays: [
      "Record and calibrated simulation overlaid per channel, before and after adding the named effects",
      "Record vs simulation, before and after",
    ],
    gap_budget: [
      "Gap budget: each named effect's share of the nominal model's excess residual energy and what is left, beside the residual per channel before and after the effects",
      "The gap budget",
    ],
    missing_term: [
      "Estimated missing term: the signal the model lacks, at the locus the data point to",
      "The missing term",
    ],
  };

  function figureText(name) {
    return FIGURES[name] || [`Figure ${words(name)} of the diagnosis`, words(name)];
  }

  function effectPhrase(e) {
    const alt = (e.alternatives || []).length
      ? ` (indistinguishable from ${e.alternatives.map(words).join(", ")})`
      : "";
    const near = (e.near_twins || []).length
      ? ` (this record cannot tell it from ${e.near_twins
          .map((t) => `${words(t.effect)} = ${valueText(t.value, null, t.unit)}`)
          .join(" or ")})`
      : "";
    const share = e.share !== undefined && e.share !== null ? `, ${pct(e.share)} of the gap` : "";
    const where = e.locus ? `, at the ${words(e.locus)}` : "";
    return `${words(e.effect)} = ${valueText(e.value, e.uncertainty, e.unit)}${share}${where}${alt}${near}`;
  }

  const HEADLINES = {
    explained: "Explained",
    partly_explained: "Partly explained",
    unexplained: "Unexplained",
    weak_gap: "Weak gap",
    no_gap: "No gap",
  };

  // The verdict as sentences a person reads: what is wrong, how sure, where, and how far the gap shrinks.
  function verdictSentences(d) {
    const r = d.result || {};
    const v = r.verdict || {};
    const status = r.status || v.status || d.status;
    const effects = v.effects || [];
    const out = [];
    if (status === "explained" || status === "partly_explained") {
      const named = effects.length ? effects.map(effectPhrase).join("; and ") : words(v.effect);
      out.push(
        status === "explained"
          ? `The gap between the record and the model is explained by ${named}.`
          : `The gap is partly explained by ${named}; ${pct(v.left)} of it is left.`,
      );
    } else if (status === "unexplained") {
      out.push("No effect of the catalogue explains the gap between the record and the model.");
    } else if (status === "weak_gap") {
      out.push("The record departs from the model only slightly beyond the noise (a weak gap): no effect is named.");
    } else if (status === "no_gap") {
      out.push("The model fits the record to the noise: there is no gap to explain.");
    }
    if (status !== "explained" && status !== "partly_explained" && v.locus) {
      const others = (v.locus_group || []).filter((g) => g !== v.locus);
      out.push(
        others.length
          ? `The missing physics acts at the ${words(v.locus)} or the ${others.map(words).join(" or the ")}: the recorded channels cannot tell them apart.`
          : `The missing physics acts at the ${words(v.locus)}.`,
      );
    }
    if (v.missing_term && v.missing_term.description) out.push(`Missing term: ${v.missing_term.description}.`);
    const gap = r.gap;
    if (gap && gap.before) {
      const before = gap.before.rms_over_noise;
      if (gap.after) {
        out.push(
          `The residual is ${num(before)} × the noise RMS with the nominal model and ${num(gap.after.rms_over_noise)} × with the named effects.`,
        );
      } else {
        out.push(`The residual of the nominal model is ${num(before)} × the noise RMS.`);
      }
    } else if (r.relative_error) {
      const parts = Object.entries(r.relative_error).map(([ch, e]) =>
        typeof e === "object" && e ? `${ch} ${pct(e.before)} → ${pct(e.after)}` : `${ch} ${pct(e)}`,
      );
      out.push(`Relative error before → after: ${parts.join(", ")}.`);
    }
    const w = r.width;
    if (w) {
      out.push(widthSentence(w));
    } else if (d.K !== null && d.K !== undefined) {
      out.push(`Backlash width: ${mm(d.K, 4)}${d.K_sigma ? ` ± ${mm(d.K_sigma, 2)}` : ""} mm.`);
    }
    if (status === "unexplained" && v.confidence !== undefined && v.confidence !== null) {
      out.push(`Probability that no effect of the catalogue explains the record: ${pct(v.confidence)}.`);
      if (v.locus_confidence !== undefined && v.locus_confidence !== null) {
        out.push(`Probability that the locus is right: ${pct(v.locus_confidence)}.`);
      }
    } else if (v.confidence !== undefined && v.confidence !== null) {
      out.push(`Probability that this verdict is right: ${pct(v.confidence)}.`);
    }
    return { status, headline: HEADLINES[status] || words(status) || "Verdict", sentences: out, reason: v.reason };
  }

  // The width of the model the answer ends with: the value, its 95 % interval and which model, or why there is none.
  function widthSentence(w) {
    const best = String(w.from || "").startsWith("best fit: ");
    const named = best ? String(w.from).slice("best fit: ".length) : w.from;
    const source =
      named === "nominal"
        ? best ? "the nominal model, the best fit" : "the nominal model"
        : `${best ? "the best-fitting model, " : "the model with "}${words(named).replace(/\+/g, " + ")}`;
    if (!w.identifiable || w.K === null || w.K === undefined) {
      return `Backlash width: not identifiable${w.reason ? ` (${w.reason})` : ""}.`;
    }
    const range = w.interval_95 ? `, 95 % interval ${mm(w.interval_95[0], 4)}–${mm(w.interval_95[1], 4)} mm` : "";
    return `Backlash width: ${mm(w.K, 4)} mm${range} (from ${source}).`;
  }

  // What makes the record doubtful for the plant, each with what to check.
  function renderWarnings(d, box, id) {
    const warnings = (d.result || {}).warnings || [];
    if (!warnings.length) return;
    const list = el("ul", "", { class: "warnings", id: id || "verdict-warnings" });
    for (const w of warnings) list.appendChild(el("li", `Check: ${w.message}`));
    box.appendChild(list);
  }

  function renderVerdict(d) {
    const box = $("verdict");
    const { status, headline, sentences, reason } = verdictSentences(d);
    box.className = `verdict status-${status || "unknown"}`;
    box.replaceChildren();
    box.appendChild(el("p", headline, { class: "headline", id: "verdict-status" }));
    const text = el("p", sentences.join(" "), { id: "verdict-text" });
    box.appendChild(text);
    if (reason) box.appendChild(el("p", `Why: ${reason}.`, { class: "reason" }));
    renderWarnings(d, box);
  }

  // Channels as columns, before and after as rows.
  function renderGap(d) {
    const table = $("gap-table");
    const head = table.querySelector("thead");
    const body = table.querySelector("tbody");
    head.replaceChildren();
    body.replaceChildren();
    const gap = (d.result || {}).gap;
    if (!gap || !gap.before) {
      table.hidden = true;
      return;
    }
    table.hidden = false;
    const channels = Object.keys(gap.before.per_channel || {});
    const top = document.createElement("tr");
    for (const name of ["", ...channels, "all channels"]) top.appendChild(el("th", name, { scope: "col" }));
    head.appendChild(top);
    const line = (label, g) =>
      row([label, ...channels.map((ch) => (g && g.per_channel[ch] ? num(g.per_channel[ch].rms_over_noise) : "–")),
        g ? num(g.rms_over_noise) : "–"], true);
    body.appendChild(line("before", gap.before));
    body.appendChild(line("after", gap.after));
  }

  function candidateCells(c, i) {
    if (c.kind === "single" || c.kind === "set") {
      const value =
        c.kind === "set"
          ? (c.effects || []).map((e) => `${words(e.effect)} ${valueText(e.value, e.uncertainty, e.unit)}`).join("; ")
          : valueText(c.value, c.uncertainty, c.unit);
      const name = c.kind === "set" ? (c.effects || []).map((e) => words(e.effect)).join(" + ") : words(c.effect);
      return [
        String(i + 1),
        name,
        value,
        num(c.delta_bic),
        num(c.weight, 2),
        c.gap_after ? `${num(c.gap_after.rms_over_noise)} × noise` : "–",
        words(c.locus || (c.effects || []).map((e) => e.locus).filter(Boolean).join(", ")),
      ];
    }
    // a plant's candidates: effects, their values, share of the gap, loci
    const values = Object.entries(c.values || {})
      .map(([k, v]) => `${words(k)} ${num(v, 4)}`)
      .join("; ");
    return [
      String(i + 1),
      (c.effects || []).map(words).join(" + "),
      values,
      "–",
      "–",
      c.share !== undefined ? `${pct(c.share)} of the gap removed` : "–",
      (c.loci || []).map(words).join(", "),
    ];
  }

  function renderCandidates(d) {
    const body = $("candidates").querySelector("tbody");
    body.replaceChildren();
    ((d.result || {}).candidates || []).forEach((c, i) => body.appendChild(row(candidateCells(c, i))));
  }

  async function renderFigures(d) {
    const box = $("figures");
    box.replaceChildren();
    const shown = [];
    const order = Object.keys(FIGURES);
    const rank = (n) => (order.includes(n) ? order.indexOf(n) : order.length);
    const names = [...(d.figures || [])].sort((a, b) => rank(a) - rank(b));
    for (const name of names) {
      const [alt, caption] = figureText(name);
      const figure = el("figure", null, { "data-figure": name });
      const img = el("img", null, { alt, "data-figure": name });
      const link = el("a", null, {
        class: "full-size",
        target: "_blank",
        rel: "noopener",
        title: "open the figure full size (new tab)",
      });
      link.appendChild(img);
      figure.appendChild(link);
      figure.appendChild(el("figcaption", caption));
      box.appendChild(figure);
      shown.push(showImage(img, `/diagnoses/${encodeURIComponent(d.id)}/figures/${encodeURIComponent(name)}`));
    }
    if (!shown.length) box.appendChild(el("p", "This diagnosis has no figures."));
    await Promise.all(shown);
  }

  async function showDiagnosis(id) {
    const d = await getJSON(`/diagnoses/${encodeURIComponent(id)}`);
    const section = $("report-section");
    section.dataset.diagnosis = d.id;
    $("report-meta").textContent = [
      `Diagnosis ${d.id}`,
      d.asset ? `drive ${d.asset}` : null,
      d.measured_at ? `measured ${dateText(d.measured_at)}` : null,
      d.plant ? `plant ${words(d.plant)}` : null,
      `state ${d.state}`,
    ]
      .filter(Boolean)
      .join(" · ");
    if (!d.result) {
      section.hidden = false;
      $("verdict").replaceChildren(el("p", `No result: the job is ${d.state}.`, { id: "verdict-text" }));
      return d;
    }
    renderVerdict(d);
    showWarnings((d.result || {}).warnings, "alert-warnings", "this diagnosis");
    renderGap(d);
    renderCandidates(d);
    section.hidden = false;
    await renderFigures(d);
    if (d.asset) {
      $("history-asset").value = d.asset;
      await showAsset();
    }
    return d;
  }

  // -- identification ------------------------------------------------------------------

  async function identify() {
    clearAlerts();
    setBusy(true);
    const channel = $("identify-channel").value;
    const continuous = $("identify-continuous").checked;
    say(`Identifying the width from ${channel}…`);
    try {
      const answer = await submitIdentification(await currentRecord(), channel, continuous);
      renderIdentification(answer);
      say("Width identified.", "ok");
      const asset = answer.asset;
      if (asset) {
        $("history-asset").value = asset;
        await showAsset();
      }
    } catch (e) {
      fail(e, "The width was not identified");
      if (e instanceof ApiError && /^no pattern set with id/.test(e.message)) loadPatternSets().catch(() => {});
      if (e instanceof ApiError && /^no record with id/.test(e.message)) loadRecords().catch(() => {});
    } finally {
      setBusy(false);
    }
  }

  function renderIdentification(a) {
    const box = $("identification");
    box.replaceChildren();
    const lines = [];
    if (a.width !== undefined) {
      lines.push(`Identified width: ${mm(a.width)} mm (class ${a.index} of ${(a.widths || []).length}, from ${a.channel}).`);
      lines.push(
        `Pattern set ${a.pattern_set} (${a.kind}, c = ${num(a.pattern_set_c)} pu, ${a.selection}); the record's network ${a.converged ? "converged" : "did not converge"} in ${a.epochs} epochs.`,
      );
    }
    const c = a.continuous;
    if (c && c.K !== undefined) {
      const sigma = c.sigma_K !== undefined && c.sigma_K !== null ? ` ± ${mm(c.sigma_K, 2)}` : "";
      const range = c.interval_95 ? `, 95 % interval ${mm(c.interval_95[0], 4)}–${mm(c.interval_95[1], 4)} mm` : "";
      lines.push(`Continuous width: ${mm(c.K, 4)}${sigma} mm${range}${c.reduced_chi2 !== undefined ? ` (fit chi²/n ${num(c.reduced_chi2)})` : ""}.`);
      if (c.identifiable === false) {
        const why = c.reason || (c.reasons || []).join("; ");
        lines.push(`Not identifiable${why ? `: ${why}` : ""}.`);
      }
    }
    if (a.identification_id) lines.push(`Stored in the drive's history (identification ${a.identification_id}).`);
    box.appendChild(el("p", lines.join(" "), { id: "identification-text" }));
    renderWarnings({ result: a }, box, "identification-warnings");
    $("identification-section").hidden = false;
    showWarnings(a.warnings, "alert-warnings", "this width");
  }

  // -- the drive's history and trend -----------------------------------------------------

  async function showAsset(event) {
    if (event) event.preventDefault();
    const asset = $("history-asset").value.trim();
    if (!asset) return;
    const limitMm = Number($("limit").value);
    const limit = Number.isFinite(limitMm) && limitMm > 0 ? limitMm / 1000 : null;
    const path = `/assets/${encodeURIComponent(asset)}`;
    const h = await getJSON(`${path}/history`);
    const body = $("history").querySelector("tbody");
    body.replaceChildren();
    for (const p of h.points || []) {
      const width = p.K !== null && p.K !== undefined ? `${mm(p.K, 4)}${p.K_sigma ? ` ± ${mm(p.K_sigma, 2)}` : ""}` : "–";
      const verdict = p.status ? `${words(p.status)}${p.effect ? `: ${words(p.effect)}` : ""}` : "–";
      const inTrend = p.used_in_trend === undefined ? "–" : p.used_in_trend ? "yes" : "no";
      body.appendChild(row([dateText(p.measured_at), p.kind, width, verdict, inTrend], true));
    }
    $("asset-report").hidden = false;
    const trend = $("trend");
    const query = limit ? `?limit=${limit}` : "";
    const method = $("trend-method");
    try {
      const t = await getJSON(`${path}/trend${query}`);
      trend.textContent = trendText(t);
      method.querySelector("p").textContent = t.method || "";
      method.hidden = !t.method;
    } catch (e) {
      if (!(e instanceof ApiError) || e.status !== 422) throw e;
      trend.textContent = `No trend yet: ${e.message}.`;
      method.hidden = true;
    }
    // the history is always drawn; the trend and the limit when the history allows
    const figure = $("trend-figure");
    figure.hidden = false;
    try {
      await showImage($("trend-image"), `${path}/trend/figure${query}`);
    } catch (e) {
      figure.hidden = true;
      // 404: no identified width to draw (a drive with diagnoses only); the history table says so
      if (!(e instanceof ApiError) || e.status !== 404) throw e;
    }
  }

  function trendText(t) {
    const perDay = (x) => `${num(x * 1e6)} µm/day`;
    const parts = [
      `The width grows by ${perDay(t.rate_m_per_day)} ± ${perDay(t.rate_sigma_m_per_day)} (1 sigma, ${t.n_points} estimates).`,
    ];
    const limit = t.limit !== undefined ? `the limit of ${mm(t.limit)} mm` : "the limit";
    if (t.crossing_date) {
      const [early, late] = t.crossing_interval || [];
      const conf = t.confidence ? `${pct(t.confidence)} ` : "";
      parts.push(
        `It reaches ${limit} on ${dateText(t.crossing_date)} (${conf}interval ${early ? dateText(early) : "unbounded"} to ${late ? dateText(late) : "unbounded"}).`,
      );
    } else {
      parts.push(`It does not reach ${limit} on the fitted trend.`);
      if (t.message) parts.push(t.message);
    }
    return parts.join(" ");
  }

  // -- start ---------------------------------------------------------------------------

  function start() {
    const stored = apiKey();
    if (stored) $("api-key").value = stored;
    $("key-form").addEventListener("submit", (e) => {
      e.preventDefault();
      clearAlerts();
      sessionStorage.setItem(KEY_STORAGE, $("api-key").value.trim());
      say("API key set for this tab.", "ok");
      refreshLists();
    });
    $("record-form").addEventListener("submit", diagnose);
    $("identify-button").addEventListener("click", identify);
    $("cancel-button").addEventListener("click", cancel);
    $("refresh-records").addEventListener("click", () => {
      clearAlerts();
      loadRecords().catch((e) => fail(e, "The stored records were not listed"));
    });
    $("asset-form").addEventListener("submit", (e) => {
      clearAlerts();
      showAsset(e).catch((err) => fail(err, "The drive's history was not shown"));
    });
    $("stored-record").addEventListener("change", () => {
      const option = $("stored-record").selectedOptions[0];
      if (option && option.dataset.plant) $("plant").value = option.dataset.plant;
    });
    refreshLists();
    const id = new URLSearchParams(location.search).get("diagnosis");
    if (id) showDiagnosis(id).catch((e) => fail(e, "The diagnosis was not shown"));
    document.body.dataset.ready = "true";
  }

  function refreshLists() {
    if (document.body.dataset.apiKeyRequired === "true" && !apiKey()) {
      askForKey();
      return;
    }
    loadRecords().catch((e) => fail(e, "The stored records were not listed"));
    loadAssets().catch(() => {});
    loadPatternSets().catch(() => {});
    loadPlants().catch(() => {});
  }

  start();
})();
