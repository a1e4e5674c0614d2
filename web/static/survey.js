// The participant flow of a paired-comparison study, on top of the JSON API (docs/design.md);
// a rating study (`kind = "rating"`) shows one image and a 5-point scale instead (`showRating`).
// Stages: welcome and consent → demographics → instructions → trials → completion.
// The participant's id and token are kept in localStorage (per study; a preview's pilot in the
// tab's sessionStorage), never in the address bar, so reloading or coming back with the same link
// resumes at the next unanswered trial.
// A join sends the kept token: a study with one run per external id resumes that run only for it.
// A response is sent until the server confirms it (201, or 200 for a repeat) before the next
// trial or the completion page is shown, so no answer is lost to a reload or a redirect.
//
// Every stored answer must be one the participant gave on purpose, so an answer counts only
// when: both images of the pair are decoded and on screen; the study's `min_response_ms` has
// passed since then; the press began after the pair was shown and after the answer lock (below);
// it is not the second or third click of a multi-click (`event.detail > 1`; a double tap is one
// on touch screens); the key is not an auto-repeat of a held key; and the trial has not been
// answered already. The answer lock: after an answer, and after the click on "Start", no press
// that begins within the study's `answer_lock_ms` answers, so the second click of a slow double
// click (or a double tap) never answers the next trial, even where the browser counts it as a
// click of its own. The server flags responses faster than `min_response_ms` by its own clock as
// well, and refuses answers to trials it never served.
"use strict";

(function () {
  const body = document.body;
  const slug = body.dataset.study;
  const studyOpen = body.dataset.open === "true";
  const minResponseMs = Number(body.dataset.minResponseMs || 0);
  const answerLockMs = Number(body.dataset.answerLockMs || 0);
  const display = body.dataset.display || "native";
  const query = new URLSearchParams(location.search);
  // An admin preview link (`?preview=TOKEN`): the participant is a pilot, kept apart, and only
  // for reloads of this tab: opening a preview link again always starts a fresh pilot.
  const preview = query.get("preview") || null;
  const storageKey = "mrstudy:" + slug + (preview ? ":preview" : "");
  const $ = (id) => document.getElementById(id);
  // The answers this study offers: the two images, and "Not sure" where it allows ties
  // (`allow_tie`: the page then has a #choose-tie button; ↓ answers it too).
  // A rating study (`kind = "rating"`) shows one image (DCR: after its reference) and a 5-point
  // scale instead (its buttons come with the first trial; the keys 1 to 5 answer too).
  const RATING = body.dataset.rating === "true";
  const CHOICES = RATING ? [] : $("choose-tie") ? ["left", "right", "tie"] : ["left", "right"];
  function enableChoices(enabled) {
    for (const choice of CHOICES) $("choose-" + choice).disabled = !enabled;
    for (const button of document.querySelectorAll("#scale .rate")) button.disabled = !enabled;
  }

  let session = null; // {participant, token, started}
  let current = null; // the trial shown
  let shownAt = Infinity; // performance.now() when both images were on screen
  let accepting = false;
  const answered = new Set(); // trials answered in this page
  // When the press now under way began (pointerdown on a choice, or a fresh keydown), in the
  // clock of performance.now(); an answer needs a press that began after the pair was shown.
  let pressedAt = -Infinity;
  // No press that begins before this (the performance.now() clock) answers: the answer lock
  // after an answer or the click on "Start".
  let lockedUntil = -Infinity;
  // The lock from an event at `at` (its timeStamp) on; from now if the page is running late.
  function lock(at) {
    lockedUntil = Math.max(at || 0, performance.now()) + answerLockMs;
  }
  const needOrientation = body.dataset.orientation || "";
  const minViewport = (body.dataset.minViewport || "").split(",").map(Number).filter((n) => n > 0);
  let screenOut = null; // id of this visitor's screen-out record, if the screen did not fit
  try { screenOut = sessionStorage.getItem(storageKey + ":screen-out"); } catch (error) { /* none */ }

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

  // Whether the kind of device comes from the user agent or the pointer (a phone stays a phone),
  // not from the window's size alone (a window made larger stops counting as a phone).
  function deviceKindFixed() {
    const ua = navigator.userAgent || "";
    const coarseOnly = window.matchMedia && matchMedia("(pointer: coarse)").matches && !matchMedia("(any-pointer: fine)").matches;
    return coarseOnly || /iPhone|iPod|Android|Mobile.*Firefox|Windows Phone|iPad|Tablet/i.test(ua)
      || (/Macintosh/.test(ua) && navigator.maxTouchPoints > 1);
  }

  // The kind of device, from the user agent, the pointer and the screen's short side.
  function deviceKind() {
    const ua = navigator.userAgent || "";
    const shortSide = Math.min(window.screen.width || 0, window.screen.height || 0) || Math.min(window.innerWidth, window.innerHeight);
    const coarseOnly = window.matchMedia && matchMedia("(pointer: coarse)").matches && !matchMedia("(any-pointer: fine)").matches;
    if (/iPhone|iPod|Android.*Mobile|Mobile.*Firefox|Windows Phone/i.test(ua)) return "phone";
    if (/iPad|Tablet|Android/i.test(ua) || (/Macintosh/.test(ua) && navigator.maxTouchPoints > 1)) return "tablet";
    if (coarseOnly) return shortSide < 600 ? "phone" : "tablet";
    // A phone-sized portrait window (an emulator, a browser that hides its kind) counts as a phone.
    if (shortSide < 500 || (window.innerWidth < 520 && window.innerHeight > window.innerWidth)) return "phone";
    return "desktop";
  }

  function clientInfo() {
    return {
      device: deviceKind(),
      viewport: [window.innerWidth, window.innerHeight],
      screen: [window.screen.width, window.screen.height],
      devicePixelRatio: window.devicePixelRatio || 1,
      userAgent: navigator.userAgent,
      language: navigator.language || "",
    };
  }

  // Whether this page was reloaded (or came back by Back/Forward) rather than opened afresh.
  function reopened() {
    const entry = performance.getEntriesByType && performance.getEntriesByType("navigation")[0];
    return !!entry && (entry.type === "reload" || entry.type === "back_forward");
  }

  // The session is kept in the browser's storage, never in the address bar (where it would be
  // copied with the link, shared in a screenshot or kept in the history): a participant's in
  // localStorage per study (another tab or a later visit resumes it), a preview's pilot in this
  // tab's sessionStorage per preview link, read only when the page is reloaded, so that opening
  // a preview link again (even in this tab) starts a fresh pilot. An address with the old
  // `#p=…&t=…` fragment (a page from before) is read once, kept, and taken off the address.
  const previewKey = storageKey + ":" + (preview || "");
  function loadSession() {
    const fragment = new URLSearchParams(location.hash.slice(1));
    let stored = null;
    try {
      stored = preview
        ? (reopened() ? JSON.parse(sessionStorage.getItem(previewKey) || "null") : null)
        : JSON.parse(localStorage.getItem(storageKey) || "null");
    } catch (error) { /* storage unavailable */ }
    if (fragment.get("p") && fragment.get("t")) {
      const same = stored && stored.participant === fragment.get("p");
      return { participant: fragment.get("p"), token: fragment.get("t"),
        started: fragment.get("s") === "1" || !!(same && stored.started) };
    }
    if (stored && stored.participant && stored.token) return stored;
    return null;
  }

  function saveSession() {
    let kept = false;
    try {
      if (preview) sessionStorage.setItem(previewKey, JSON.stringify(session));
      else localStorage.setItem(storageKey, JSON.stringify(session));
      kept = true;
    } catch (error) { /* private mode without storage */ }
    if (kept) {
      if (location.hash) history.replaceState(null, "", location.pathname + location.search);
      return;
    }
    // Without any storage the fragment is the only place a reload can find the session.
    const fragment = new URLSearchParams({ p: session.participant, t: session.token });
    if (session.started) fragment.set("s", "1");
    history.replaceState(null, "", location.pathname + location.search + "#" + fragment.toString());
  }

  // The token this browser keeps for the study link (from a join in this tab or another), sent
  // with a join: where a study keeps one run per external id, only that run's token resumes it.
  function keptToken() {
    if (session && session.token) return session.token;
    try {
      const stored = JSON.parse(localStorage.getItem(storageKey) || "null");
      if (stored && stored.token) return stored.token;
    } catch (error) { /* storage unavailable */ }
    return undefined;
  }

  function forgetSession() {
    try { if (preview) sessionStorage.removeItem(previewKey); else localStorage.removeItem(storageKey); } catch (error) { /* ignore */ }
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
    return { status: response.status, data, retryAfter: Number(response.headers.get("Retry-After")) || 0 };
  }

  // A message on the stage in view (null clears it).
  function notice(text) {
    const element = $("stage-trial").hidden ? $("demographics-error") : $("trial-error");
    element.textContent = text || "";
    element.hidden = !text;
  }

  const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

  // Retries network failures and 5xx answers with backoff, and a 429 (over a limit: many people
  // behind one address) after the server's Retry-After, the same request with the same answer;
  // returns the first other answer.
  async function persistent(method, path, payload) {
    let delay = 500;
    for (let attempt = 0; ; attempt++) {
      try {
        const answer = await api(method, path, payload);
        if (answer.status === 429) {
          const seconds = Math.min(Math.max(answer.retryAfter, 1), 300);
          notice("Many people are taking part at once: nothing is lost, sending again in " + seconds + " s…");
          await sleep(seconds * 1000);
          continue;
        }
        if (answer.status === 503 && answer.retryAfter) {
          // the next trial's images are still being rendered (or the study opens soon): the
          // server's own sentence, then the same request after its Retry-After
          notice((answer.data && answer.data.error) || "Please wait a moment…");
          await sleep(Math.min(Math.max(answer.retryAfter, 1), 300) * 1000);
          continue;
        }
        if (answer.status < 500) { notice(null); return answer; }
      } catch (error) { /* network error: retry */ }
      if (attempt >= 1) notice("Connection problem: your answers are being saved, please wait…");
      await sleep(delay);
      delay = Math.min(delay * 2, 8000);
    }
  }

  function urlParams() {
    const kept = {};
    for (const [key, value] of query) if (key !== "preview") kept[key] = value;
    return kept;
  }

  // Checks the screen against the study's requirements (server side, so the sentence and the
  // record are the same for everybody). Resolves with the server's answer when it fits (with
  // `completed` when the study's external id in the URL already finished: a returning
  // participant); until then the visitor sees one sentence, is counted as screened out, and the
  // check runs again when the window changes.
  function screenFits() {
    return new Promise((resolve) => {
      let timer = null;
      async function check() {
        const answer = await persistent("POST", "/api/studies/" + encodeURIComponent(slug) + "/screen",
          { client: clientInfo(), url_params: urlParams(), preview, screen_out: screenOut });
        if (answer.status === 200 && answer.data && answer.data.meets) {
          window.removeEventListener("resize", later);
          resolve(answer.data);
          return;
        }
        if (answer.status === 201 && answer.data) {
          screenOut = answer.data.screen_out;
          try { sessionStorage.setItem(storageKey + ":screen-out", screenOut); } catch (error) { /* none */ }
          $("screen-reason").textContent = answer.data.reason;
          // Only a window's size or orientation can change on this page (the check runs again
          // when it does); a device of the wrong kind stays one.
          $("screen-hint").textContent = answer.data.fixable === false && deviceKindFixed()
            ? "The study cannot be done on this device; you can close this page."
            : "If you change this (a larger window, turning the device), this page goes on by itself.";
          show("screen");
          return;
        }
        window.removeEventListener("resize", later);
        fatal((answer.data && answer.data.error) || "The study could not start.");
      }
      function later() { clearTimeout(timer); timer = setTimeout(check, 400); }
      window.addEventListener("resize", later);
      check();
    });
  }

  async function start() {
    session = loadSession();
    if (session) {
      saveSession();
      // A reload before "Start" shows the instructions again instead of skipping them.
      if (session.started) await nextTrial(); else show("instructions");
    } else if (!studyOpen && !preview) {
      show("closed");
    } else {
      const fits = await screenFits();
      if (fits.completed) finish(fits.completed); else show("welcome");
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
      const name = label ? label.textContent.replace(/ \(optional\)$/, "") : "all questions";
      const validity = invalid ? invalid.validity : null;
      if (validity && (validity.rangeUnderflow || validity.rangeOverflow || validity.stepMismatch || validity.badInput)) {
        const min = invalid.getAttribute("min"), max = invalid.getAttribute("max");
        const range = min && max ? " from " + min + " to " + max : min ? " of at least " + min : max ? " of at most " + max : "";
        error.textContent = name + ": please enter a whole number" + range + ".";
      } else {
        error.textContent = "Please answer: " + name + ".";
      }
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
    $("demographics-continue").disabled = true;
    try {
      const answer = await persistent("POST", "/api/studies/" + encodeURIComponent(slug) + "/participants",
        { demographics, client: clientInfo(), url_params: urlParams(), preview, screen_out: screenOut, token: keptToken() });
      if (answer.status === 201 || answer.status === 200) {
        session = { participant: answer.data.participant, token: answer.data.token, started: false };
        try { sessionStorage.removeItem(storageKey + ":screen-out"); } catch (error) { /* none */ }
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

  $("start").addEventListener("click", (event) => {
    // a second (or third) click of a multi-click
    if (!session || session.started || event.detail > 1) return;
    lock(event.timeStamp);
    session.started = true;
    saveSession();
    $("start").disabled = true;
    nextTrial();
  });

  async function nextTrial() {
    accepting = false;
    shownAt = Infinity;
    const answer = await persistent("GET", "/api/participants/" + encodeURIComponent(session.participant) + "/next");
    if (answer.status === 403) {
      // This page's token no longer answers for the participant, as for an answer (below): the
      // same words, and the kept session stays (another tab may be going on with it).
      fatal(GONE_ELSEWHERE);
      return;
    }
    if (answer.status === 401 || answer.status === 404) {
      forgetSession();
      if (studyOpen) show("welcome"); else show("closed");
      return;
    }
    if (answer.status !== 200) { fatal((answer.data && answer.data.error) || "The next trial could not be loaded."); return; }
    if (answer.data.done) { finish(answer.data); return; }
    await showTrial(answer.data);
  }

  // Resolves true when the image is loaded and decoded, false when it cannot be.
  function decode(image, url) {
    return new Promise((resolve) => {
      image.onload = () => resolve(true);
      image.onerror = () => resolve(false);
      image.src = url;
      if (image.complete && image.naturalWidth > 0) resolve(true);
    }).then((loaded) => loaded && (image.decode ? image.decode().then(() => true, () => image.naturalWidth > 0) : true));
  }

  async function showTrial(trial) {
    if (trial.rating) { await showRating(trial); return; }
    current = trial;
    pressedAt = -Infinity;
    show("trial");
    const left = $("image-left"), right = $("image-right");
    $("pair").classList.add("loading");
    const loadingNote = setTimeout(() => { if (current === trial) $("pair-loading").hidden = false; }, 150);
    enableChoices(false);
    $("trial-progress").textContent = "Trial " + trial.trial + " of " + trial.total;
    $("trial-question").textContent = trial.question;
    $("progress-fill").style.width = (100 * (trial.trial - 1) / trial.total) + "%";
    left.alt = trial.left.alt; right.alt = trial.right.alt;
    const loaded = await Promise.all([decode(left, trial.left.url), decode(right, trial.right.url)]);
    clearTimeout(loadingNote);
    if (current !== trial) return;
    if (!loaded[0] || !loaded[1]) {
      // An image did not arrive: say so and load the trial again (it stays unanswerable).
      notice("The images could not be loaded; trying again…");
      await sleep(1500);
      if (current === trial) { left.removeAttribute("src"); right.removeAttribute("src"); await nextTrial(); }
      return;
    }
    notice(null);
    layout();
    $("pair-loading").hidden = true;
    $("pair").classList.remove("loading");
    enableChoices(true);
    // Both images are painted after the next frame: the response time counts from there.
    requestAnimationFrame(() => requestAnimationFrame(() => {
      if (current !== trial) return;
      shownAt = performance.now();
      accepting = true;
      body.dataset.trial = String(trial.trial);
    }));
    for (const url of trial.preload || []) { const image = new Image(); image.src = url; }
  }

  // Both images at one scale (the same on-screen size for equal image sizes), as large as the
  // viewport allows side by side, without scrolling.
  function layout() {
    if (RATING) { layoutRated(); return; }
    const left = $("image-left"), right = $("image-right");
    if (!left.naturalWidth || !right.naturalWidth) return;
    const pair = $("pair");
    const border = 8; // the buttons' borders, both sides
    const gap = parseFloat(getComputedStyle(pair).columnGap) || 0;
    let below = 0;
    for (const hint of document.querySelectorAll("#stage-trial .hint, #stage-trial .tie-row")) below += hint.offsetHeight;
    const width = (pair.clientWidth - gap) / 2 - border;
    const height = window.innerHeight - pair.getBoundingClientRect().top - below - border - 12;
    let scale = Math.max(0.05, Math.min(
      width / left.naturalWidth, width / right.naturalWidth,
      height / left.naturalHeight, height / right.naturalHeight));
    // `display = "native"`: never more than one image pixel per device pixel (no resampling
    // upward: at a device pixel ratio of 2 an image takes half its pixel size in CSS pixels);
    // `display = "css"`: never more than one image pixel per CSS pixel (the same CSS size on
    // every screen, enlarged by the browser on HiDPI screens); `fit`: as large as there is room.
    if (display === "native") scale = Math.min(scale, 1 / (window.devicePixelRatio || 1));
    else if (display === "css") scale = Math.min(scale, 1);
    for (const image of [left, right]) {
      image.style.width = Math.floor(image.naturalWidth * scale) + "px";
      image.style.height = Math.floor(image.naturalHeight * scale) + "px";
    }
  }
  window.addEventListener("resize", () => { if (!$("stage-trial").hidden) { layout(); checkScreenDuringTrials(); } });

  // During the trials the window must still meet the study's orientation and size (a phone
  // turned mid-study): until it does again, a sentence says so and no answer is taken.
  function screenWarning() {
    const width = window.innerWidth, height = window.innerHeight;
    if (needOrientation === "landscape" && width < height) return "Please turn your device back to landscape (wider than tall) to go on.";
    if (needOrientation === "portrait" && width > height) return "Please turn your device back to portrait (taller than wide) to go on.";
    if (minViewport.length === 2 && (width < minViewport[0] || height < minViewport[1])) {
      return "Please make the window at least " + minViewport[0] + " × " + minViewport[1] + " pixels again to go on.";
    }
    return null;
  }
  function checkScreenDuringTrials() {
    const warning = screenWarning();
    $("screen-warning").textContent = warning || "";
    $("screen-warning").hidden = !warning;
    return !warning;
  }

  // The size the left image is shown at (both are at one scale), in CSS and device pixels.
  function shownSize() {
    const box = $(RATING ? "rated-stimulus" : "image-left").getBoundingClientRect();
    const ratio = window.devicePixelRatio || 1;
    const css = [Math.round(box.width * 100) / 100, Math.round(box.height * 100) / 100];
    return { css, device: [Math.round(box.width * ratio), Math.round(box.height * ratio)] };
  }

  // `at`: the time of the event that answers (its timeStamp), from which the answer lock runs.
  function choose(side, pressed, at) {
    return send({ chosen: side }, $("choose-" + side), pressed, at);
  }

  // Sends the answer `fields` (`{chosen}` or `{rating}`) given by a press on `button`.
  async function send(fields, button, pressed, at) {
    if (!accepting || !current || answered.has(current.trial)) return;
    if (!checkScreenDuringTrials()) return;
    if (!(pressed >= shownAt) || !(pressed >= lockedUntil)) return;
    if (performance.now() - shownAt < minResponseMs) return;
    accepting = false;
    lock(at);
    const rtMs = Math.round((performance.now() - shownAt) * 10) / 10;
    const shown = shownSize();
    const trial = current;
    answered.add(trial.trial);
    enableChoices(false);
    // No focus or highlight carries over to the next pair (on touch screens the tapped side
    // would look pre-selected); the focus goes to the question above the pair (no ring), so
    // that Tab moves to the left image next, after a mouse answer as after a keyboard one (a
    // plain blur left the Tab starting point at the clicked image: from the right one, Tab left
    // the page and Enter answered nothing).
    const question = $("trial-question");
    question.tabIndex = -1;
    question.focus({ preventScroll: true });
    button.classList.add("chosen");
    const answer = await persistent("POST", "/api/participants/" + encodeURIComponent(session.participant) + "/responses",
      Object.assign({ trial: trial.trial }, fields, { rt_ms: rtMs, client: clientInfo(), display: shown }));
    button.classList.remove("chosen");
    if (answer.status === 201 || answer.status === 200 || answer.status === 409) {
      if (answer.status === 409) answered.delete(trial.trial);
      // 409: this trial was answered in another tab; continue where the server is.
      await nextTrial();
    } else if (answer.status === 403) {
      // This page's token no longer answers for the participant (the run goes on elsewhere with
      // its own token, or the researcher removed it): say so in words, not the server's.
      fatal(GONE_ELSEWHERE);
    } else {
      fatal((answer.data && answer.data.error) || "The answer could not be saved.");
    }
  }
  const GONE_ELSEWHERE = "This page can no longer save your answers. If you resumed the study in another tab or window, it continues there: please go on there and close this one. Otherwise, please contact the researcher.";


  // ---- Rating trials (`kind = "rating"`, ITU-T P.910) ----
  // The scale's buttons, best first, each with its number (its key) and its standard label;
  // made once from the first trial's scale.
  function buildScale(points) {
    const scale = $("scale");
    if (scale.childElementCount) return;
    for (const point of points) {
      const button = document.createElement("button");
      button.type = "button";
      button.className = "rate";
      button.id = "rate-" + point.rating;
      button.disabled = true;
      button.setAttribute("aria-keyshortcuts", String(point.rating));
      const value = document.createElement("span");
      value.className = "rate-value";
      value.textContent = String(point.rating);
      const label = document.createElement("span");
      label.className = "rate-label";
      label.textContent = point.label;
      button.append(value, label);
      button.addEventListener("pointerdown", (event) => { pressedAt = event.timeStamp; });
      button.addEventListener("click", (event) => {
        const pressed = pressedAt;
        pressedAt = -Infinity;
        if (event.detail > 1) return; // the second click of a double click never answers
        rate(point.rating, pressed, event.timeStamp);
      });
      scale.appendChild(button);
    }
  }

  function rate(rating, pressed, at) {
    const button = $("rate-" + rating);
    if (button) send({ rating }, button, pressed, at);
  }

  // Which part of a rating trial is on screen: "reference", "stimulus", "both" (DCR side by
  // side) or "grey" (P.910's mid-grey between and after the images).
  let ratedPhase = "stimulus";
  function phase(what) {
    ratedPhase = what;
    $("rated-reference-figure").hidden = !(what === "reference" || what === "both");
    $("rated-stimulus-figure").hidden = !(what === "stimulus" || what === "both");
    $("rated-grey").hidden = what !== "grey";
    // the grey keeps the caption's room, so the scale does not move between the phases
    $("rated-grey").classList.toggle("captioned", !!(current && current.reference));
    body.dataset.phase = what;
    layoutRated();
  }

  // The image (and DCR's reference) at one scale, as large as the window allows above the scale.
  function layoutRated() {
    const stimulus = $("rated-stimulus"), reference = $("rated-reference");
    if (!stimulus.naturalWidth) return;
    const both = ratedPhase === "both";
    const rated = $("rated");
    const gap = both ? 16 : 0;
    let below = $("scale").offsetHeight + 24;
    for (const hint of document.querySelectorAll("#stage-trial .hint")) below += hint.offsetHeight;
    const captions = current && current.reference ? 24 : 0;
    const width = (rated.clientWidth - gap) / (both ? 2 : 1);
    const height = window.innerHeight - rated.getBoundingClientRect().top - below - captions;
    const images = reference.naturalWidth && current && current.reference ? [stimulus, reference] : [stimulus];
    let scale = Math.max(0.05, Math.min(...images.map((image) => Math.min(width / image.naturalWidth, height / image.naturalHeight))));
    if (display === "native") scale = Math.min(scale, 1 / (window.devicePixelRatio || 1));
    else if (display === "css") scale = Math.min(scale, 1);
    for (const image of images) {
      image.style.width = Math.floor(image.naturalWidth * scale) + "px";
      image.style.height = Math.floor(image.naturalHeight * scale) + "px";
    }
    $("rated-grey").style.width = stimulus.style.width;
    $("rated-grey").style.height = stimulus.style.height;
  }

  // A rating trial as P.910 presents it: in sequential DCR the reference for `stimulus_ms`, the
  // grey for `grey_ms`, then the stimulus; the stimulus for `stimulus_ms` (0: until the vote),
  // then the grey. The scale takes answers from the stimulus's onset, or with `vote_after` only
  // once it has gone; the response time counts from then.
  async function showRating(trial) {
    current = trial;
    pressedAt = -Infinity;
    accepting = false;
    show("trial");
    buildScale(trial.rating.points);
    enableChoices(false);
    $("trial-progress").textContent = "Trial " + trial.trial + " of " + trial.total;
    $("trial-question").textContent = trial.question;
    $("progress-fill").style.width = (100 * (trial.trial - 1) / trial.total) + "%";
    const rated = $("rated");
    rated.classList.add("loading");
    const loadingNote = setTimeout(() => { if (current === trial) $("pair-loading").hidden = false; }, 150);
    const stimulus = $("rated-stimulus"), reference = $("rated-reference");
    stimulus.alt = trial.stimulus.alt;
    $("rated-stimulus-caption").hidden = !trial.reference;
    const loads = [decode(stimulus, trial.stimulus.url)];
    if (trial.reference) { reference.alt = trial.reference.alt; loads.push(decode(reference, trial.reference.url)); }
    else reference.removeAttribute("src");
    const loaded = await Promise.all(loads);
    clearTimeout(loadingNote);
    if (current !== trial) return;
    if (loaded.includes(false)) {
      notice("The image could not be loaded; trying again…");
      await sleep(1500);
      if (current === trial) { stimulus.removeAttribute("src"); reference.removeAttribute("src"); await nextTrial(); }
      return;
    }
    notice(null);
    $("pair-loading").hidden = true;
    const rule = trial.rating;
    const sequential = !!trial.reference && rule.layout === "sequential";
    const still = () => current === trial && !answered.has(trial.trial);
    const wait = (ms) => sleep(ms).then(still);
    const painted = () => new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve)));
    if (sequential) {
      phase("reference");
      rated.classList.remove("loading");
      await painted();
      if (!(await wait(rule.stimulus_ms))) return;
      if (rule.grey_ms > 0) { phase("grey"); if (!(await wait(rule.grey_ms))) return; }
    }
    phase(trial.reference && !sequential ? "both" : "stimulus");
    rated.classList.remove("loading");
    await painted();
    if (!still()) return;
    const open = () => {
      enableChoices(true);
      shownAt = performance.now();
      accepting = true;
      body.dataset.trial = String(trial.trial);
    };
    if (!rule.vote_after) open();
    for (const url of trial.preload || []) { const image = new Image(); image.src = url; }
    if (rule.stimulus_ms > 0) {
      if (!(await wait(rule.stimulus_ms))) return;
      phase("grey");
      if (rule.vote_after) { await painted(); if (still()) open(); }
    }
  }

  for (const side of CHOICES) {
    const button = $("choose-" + side);
    button.addEventListener("pointerdown", (event) => { pressedAt = event.timeStamp; });
    // A click from the keyboard (Enter or Space on the focused image) has no pointerdown: its
    // press began at the keydown, which is recorded below.
    button.addEventListener("click", (event) => {
      const pressed = pressedAt;
      pressedAt = -Infinity;
      // The second click of a double click (or tap) never answers, whatever its timing.
      if (event.detail > 1) return;
      choose(side, pressed, event.timeStamp);
    });
  }
  document.addEventListener("keydown", (event) => {
    if ($("stage-trial").hidden || event.altKey || event.ctrlKey || event.metaKey) return;
    const arrow = RATING ? null : event.key === "ArrowLeft" ? "left" : event.key === "ArrowRight" ? "right"
      : event.key === "ArrowDown" && CHOICES.includes("tie") ? "tie" : null;
    const digit = RATING && /^[1-5]$/.test(event.key) ? Number(event.key) : null;
    if (arrow || digit || event.key === "Enter" || event.key === " ") {
      // A held key repeats: only its first press counts, and only once.
      if (event.repeat) { event.preventDefault(); return; }
      pressedAt = event.timeStamp;
    }
    if (arrow) {
      event.preventDefault();
      const pressed = pressedAt;
      pressedAt = -Infinity;
      choose(arrow, pressed, event.timeStamp);
    }
    if (digit) {
      event.preventDefault();
      const pressed = pressedAt;
      pressedAt = -Infinity;
      rate(digit, pressed, event.timeStamp);
    }
  }, true);

  // Leaving mid-study (Back, closing the tab, another address) asks first: from "Start" until
  // the completion page, not before (nothing to lose) nor after (the redirect must not ask).
  let finished = false;
  window.addEventListener("beforeunload", (event) => {
    if (!session || !session.started || finished) return;
    event.preventDefault();
    event.returnValue = "";
  });

  function finish(done) {
    finished = true;
    body.dataset.trial = "done";
    $("completion-code").textContent = done.completion_code;
    show("done");
    if (done.redirect) {
      $("redirect-link").href = done.redirect;
      $("redirect-note").hidden = false;
      setTimeout(() => { location.href = done.redirect; }, 3000);
    }
  }

  $("retry").addEventListener("click", () => { if (session && session.started) nextTrial(); else if (session) show("instructions"); else show("welcome"); });

  if (preview) $("preview-note").hidden = false;
  // A touch screen without a mouse (a phone, most tablets) is told to tap: it has no mouse to
  // click with and mostly no arrow keys.
  const touchOnly = window.matchMedia && matchMedia("(pointer: coarse)").matches && !matchMedia("(any-pointer: fine)").matches;
  if (touchOnly || deviceKind() === "phone") $("choice-hint").textContent = RATING ? "Tap a rating." : "Tap an image.";
  start().catch((error) => fatal("The study could not start: " + error));
})();
