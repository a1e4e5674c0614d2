// The participant flow of a paired-comparison study, on top of the JSON API (DESIGN.md).
// Stages: welcome and consent → demographics → instructions → trials → completion.
// The participant's id and token are kept in localStorage (per study) and in the page's URL
// fragment, so reloading or coming back with the same link resumes at the next unanswered trial.
// A response is sent until the server confirms it (201, or 200 for a repeat) before the next
// trial or the completion page is shown, so no answer is lost to a reload or a redirect.
"use strict";

(function () {
  const body = document.body;
  const slug = body.dataset.study;
  const studyOpen = body.dataset.open === "true";
  const storageKey = "mrstudy:" + slug;
  const $ = (id) => document.getElementById(id);

  let session = null; // {participant, token}
  let current = null; // the trial shown
  let shownAt = 0; // performance.now() when both images were on screen
  let accepting = false;

  function show(stage) {
    for (const section of document.querySelectorAll("main > section")) {
      section.hidden = section.id !== "stage-" + stage;
    }
    const heading = document.querySelector("#stage-" + stage + " h1");
    if (heading) { heading.tabIndex = -1; heading.focus(); }
  }

  function fatal(message) {
    $("fatal-error").textContent = message;
    show("error");
  }

  function clientInfo() {
    return {
      viewport: [window.innerWidth, window.innerHeight],
      screen: [window.screen.width, window.screen.height],
      devicePixelRatio: window.devicePixelRatio || 1,
      userAgent: navigator.userAgent,
      language: navigator.language || "",
    };
  }

  function loadSession() {
    const fragment = new URLSearchParams(location.hash.slice(1));
    if (fragment.get("p") && fragment.get("t")) {
      return { participant: fragment.get("p"), token: fragment.get("t") };
    }
    try {
      const stored = JSON.parse(localStorage.getItem(storageKey) || "null");
      if (stored && stored.participant && stored.token) return stored;
    } catch (error) { /* storage unavailable */ }
    return null;
  }

  function saveSession() {
    try { localStorage.setItem(storageKey, JSON.stringify(session)); } catch (error) { /* private mode */ }
    const fragment = new URLSearchParams({ p: session.participant, t: session.token });
    history.replaceState(null, "", location.pathname + location.search + "#" + fragment.toString());
  }

  function forgetSession() {
    try { localStorage.removeItem(storageKey); } catch (error) { /* ignore */ }
    history.replaceState(null, "", location.pathname + location.search);
    session = null;
  }

  async function api(method, path, payload) {
    const headers = { "Accept": "application/json" };
    if (payload !== undefined) headers["Content-Type"] = "application/json";
    if (session) headers["Authorization"] = "Bearer " + session.token;
    const response = await fetch(path, {
      method, headers, body: payload === undefined ? undefined : JSON.stringify(payload),
      cache: "no-store", credentials: "omit",
    });
    let data = null;
    try { data = await response.json(); } catch (error) { /* no body */ }
    return { status: response.status, data };
  }

  // A message on the stage in view (null clears it).
  function notice(text) {
    const element = $("stage-trial").hidden ? $("demographics-error") : $("trial-error");
    element.textContent = text || "";
    element.hidden = !text;
  }

  const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

  // Retries network failures and 5xx answers with backoff; returns the first other answer.
  async function persistent(method, path, payload) {
    let delay = 500;
    for (let attempt = 0; ; attempt++) {
      try {
        const answer = await api(method, path, payload);
        if (answer.status < 500) { notice(null); return answer; }
      } catch (error) { /* network error: retry */ }
      if (attempt >= 1) notice("Connection problem: your answers are being saved, please wait…");
      await sleep(delay);
      delay = Math.min(delay * 2, 8000);
    }
  }

  async function start() {
    session = loadSession();
    if (session) {
      saveSession();
      await nextTrial();
    } else if (!studyOpen) {
      show("closed");
    } else {
      show("welcome");
    }
  }

  $("consent-form").addEventListener("submit", (event) => {
    event.preventDefault();
    if (!$("consent").checked) return;
    show("demographics");
  });

  $("demographics-form").addEventListener("submit", async (event) => {
    event.preventDefault();
    const form = event.target;
    const error = $("demographics-error");
    if (!form.checkValidity()) {
      const invalid = form.querySelector(":invalid");
      const label = invalid ? form.querySelector('label[for="' + invalid.id + '"]') : null;
      error.textContent = "Please answer: " + (label ? label.textContent : "all questions") + ".";
      error.hidden = false;
      if (invalid) invalid.focus();
      return;
    }
    const demographics = {};
    for (const element of form.querySelectorAll("[data-kind]")) {
      const value = element.value.trim();
      if (value === "") { demographics[element.name] = null; continue; }
      demographics[element.name] = element.dataset.kind === "integer" ? Number(value) : value;
    }
    const urlParams = {};
    for (const [key, value] of new URLSearchParams(location.search)) urlParams[key] = value;
    $("demographics-continue").disabled = true;
    try {
      const answer = await persistent("POST", "/api/studies/" + encodeURIComponent(slug) + "/participants",
        { demographics, client: clientInfo(), url_params: urlParams });
      if (answer.status === 201) {
        session = { participant: answer.data.participant, token: answer.data.token };
        saveSession();
        show("instructions");
      } else {
        error.textContent = (answer.data && answer.data.error) || "The answers could not be saved.";
        error.hidden = false;
      }
    } finally {
      $("demographics-continue").disabled = false;
    }
  });

  $("start").addEventListener("click", () => nextTrial());

  async function nextTrial() {
    accepting = false;
    const answer = await persistent("GET", "/api/participants/" + encodeURIComponent(session.participant) + "/next");
    if (answer.status === 401 || answer.status === 403 || answer.status === 404) {
      forgetSession();
      if (studyOpen) show("welcome"); else show("closed");
      return;
    }
    if (answer.status !== 200) { fatal((answer.data && answer.data.error) || "The next trial could not be loaded."); return; }
    if (answer.data.done) { finish(answer.data); return; }
    await showTrial(answer.data);
  }

  function decode(image, url) {
    return new Promise((resolve) => {
      image.onload = () => resolve();
      image.onerror = () => resolve();
      image.src = url;
      if (image.complete) resolve();
    }).then(() => (image.decode ? image.decode().catch(() => {}) : undefined));
  }

  async function showTrial(trial) {
    current = trial;
    show("trial");
    const left = $("image-left"), right = $("image-right");
    $("pair").classList.add("loading");
    $("choose-left").disabled = true; $("choose-right").disabled = true;
    $("trial-progress").textContent = "Trial " + trial.trial + " of " + trial.total;
    $("trial-question").textContent = trial.question;
    $("progress-fill").style.width = (100 * (trial.trial - 1) / trial.total) + "%";
    left.alt = trial.left.alt; right.alt = trial.right.alt;
    await Promise.all([decode(left, trial.left.url), decode(right, trial.right.url)]);
    if (current !== trial) return;
    layout();
    $("pair").classList.remove("loading");
    $("choose-left").disabled = false; $("choose-right").disabled = false;
    // Both images are on screen at the next frame: the response time counts from there.
    requestAnimationFrame(() => {
      shownAt = performance.now();
      accepting = true;
      body.dataset.trial = String(trial.trial);
    });
    for (const url of trial.preload || []) { const image = new Image(); image.src = url; }
  }

  // Both images at one scale (the same on-screen size for equal image sizes), as large as the
  // viewport allows side by side, without scrolling.
  function layout() {
    const left = $("image-left"), right = $("image-right");
    if (!left.naturalWidth || !right.naturalWidth) return;
    const pair = $("pair");
    const border = 8; // the buttons' borders, both sides
    const gap = parseFloat(getComputedStyle(pair).columnGap) || 0;
    let below = 0;
    for (const hint of document.querySelectorAll("#stage-trial .hint")) below += hint.offsetHeight;
    const width = (pair.clientWidth - gap) / 2 - border;
    const height = window.innerHeight - pair.getBoundingClientRect().top - below - border - 12;
    const scale = Math.max(0.05, Math.min(
      width / left.naturalWidth, width / right.naturalWidth,
      height / left.naturalHeight, height / right.naturalHeight));
    for (const image of [left, right]) {
      image.style.width = Math.floor(image.naturalWidth * scale) + "px";
      image.style.height = Math.floor(image.naturalHeight * scale) + "px";
    }
  }
  window.addEventListener("resize", () => { if (!$("stage-trial").hidden) layout(); });

  async function choose(side) {
    if (!accepting || !current) return;
    accepting = false;
    const rtMs = Math.round((performance.now() - shownAt) * 10) / 10;
    const trial = current;
    $("choose-left").disabled = true; $("choose-right").disabled = true;
    $("choose-" + side).classList.add("chosen");
    const answer = await persistent("POST", "/api/participants/" + encodeURIComponent(session.participant) + "/responses",
      { trial: trial.trial, chosen: side, rt_ms: rtMs, client: clientInfo() });
    $("choose-" + side).classList.remove("chosen");
    if (answer.status === 201 || answer.status === 200 || answer.status === 409) {
      // 409: this trial was answered in another tab; continue where the server is.
      await nextTrial();
    } else {
      fatal((answer.data && answer.data.error) || "The answer could not be saved.");
    }
  }

  $("choose-left").addEventListener("click", () => choose("left"));
  $("choose-right").addEventListener("click", () => choose("right"));
  document.addEventListener("keydown", (event) => {
    if ($("stage-trial").hidden || event.altKey || event.ctrlKey || event.metaKey) return;
    if (event.key === "ArrowLeft") { event.preventDefault(); choose("left"); }
    if (event.key === "ArrowRight") { event.preventDefault(); choose("right"); }
  });

  function finish(done) {
    body.dataset.trial = "done";
    $("completion-code").textContent = done.completion_code;
    show("done");
    if (done.redirect) {
      $("redirect-link").href = done.redirect;
      $("redirect-note").hidden = false;
      setTimeout(() => { location.href = done.redirect; }, 3000);
    }
  }

  $("retry").addEventListener("click", () => { if (session) nextTrial(); else show("welcome"); });

  start().catch((error) => fatal("The study could not start: " + error));
})();
