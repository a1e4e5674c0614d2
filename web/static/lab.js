// The lab task page: the participant is created over HTTP (POST /api/lab/{slug}/participants,
// with the admin's preview token when the page was opened from a preview link), then one
// WebSocket session runs their trials (see studies/README.md, "The live WebSocket API", and
// docs/lab.md).
// Keys go to the server as they are pressed; frames come back as a JSON "frame" message followed
// by a binary message (u32 frame number, big-endian, then the JPEG), shown in order, and each
// frame on screen is reported back with "shown" (the server refuses answers before that).
//
// Input hygiene: auto-repeated keys (a held key) are ignored everywhere, and a key that went down
// before the current screen appeared does nothing on it, so a held Enter answers at most one
// trial and never acknowledges instructions. A held arrow key moves the cube continuously
// instead: one step when it goes down, then the task's `held_steps_per_second` steps a second
// (sent as keys with `held: true`) until it goes up, at that fixed rate whatever the system's
// auto-repeat does. The participant id and token are kept in
// localStorage (per preview link for a pilot, so a new preview link starts a fresh pilot), so a
// closed tab resumes at the next unanswered trial. No timing is shown here.
(function () {
  "use strict";
  const slug = document.body.dataset.slug;
  const $ = (id) => document.getElementById(id);
  const preview = new URLSearchParams(location.search).get("preview");
  const storageKey = "mrstudy-lab-" + slug + (preview ? ":preview:" + preview : "");
  let socket = null;
  let trial = null;
  let expectFrame = null;
  let framesShown = 0;
  let mode = "welcome"; // welcome, instructions, trial, next, done
  let screenSince = 0; // performance.now() when the current screen appeared
  let waiting = false; // a message was sent whose answer has not come yet
  let resuming = false;

  // held arrow keys: key -> the interval that sends its steps
  const held = new Map();

  function release(key) {
    const interval = held.get(key);
    if (interval !== undefined) {
      clearInterval(interval);
      held.delete(key);
    }
  }

  function releaseAll() {
    for (const key of Array.from(held.keys())) release(key);
  }

  function hold(key) {
    if (held.has(key) || !trial) return;
    const forTrial = trial.trial;
    const rate = trial.held_steps_per_second || 10;
    send({ type: "key", key: key, t: performance.now() });
    held.set(key, setInterval(() => {
      if (mode !== "trial" || !trial || trial.trial !== forTrial || waiting) {
        release(key);
        return;
      }
      send({ type: "key", key: key, t: performance.now(), held: true });
    }, 1000 / rate));
  }

  function setMode(next) {
    releaseAll();
    mode = next;
    screenSince = performance.now();
    waiting = false;
    document.body.dataset.mode = next;
  }

  function send(message) {
    if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(message));
  }

  function showError(text) {
    $("lab-error").textContent = text || "";
  }

  function remember(value) {
    try {
      if (value) localStorage.setItem(storageKey, JSON.stringify(value));
      else localStorage.removeItem(storageKey);
    } catch (e) { /* storage unavailable: no resume */ }
  }

  function connect(first) {
    const scheme = location.protocol === "https:" ? "wss:" : "ws:";
    socket = new WebSocket(scheme + "//" + location.host + "/api/lab/" + encodeURIComponent(slug) + "/ws");
    socket.binaryType = "blob";
    socket.onopen = () => send(first);
    socket.onmessage = (event) => {
      if (typeof event.data !== "string") {
        showFrame(event.data);
        return;
      }
      handle(JSON.parse(event.data));
    };
    socket.onclose = () => {
      if (mode === "done" || mode === "welcome") return;
      showError("The connection to the server was lost; reload the page to continue where you stopped.");
    };
  }

  function showFrame(blob) {
    if (!expectFrame) return;
    const meta = expectFrame;
    expectFrame = null;
    // a data: URL (the Content-Security-Policy allows data: images, not blob:)
    const reader = new FileReader();
    reader.onload = () => {
      const img = $("lab-frame");
      img.onload = () => {
        img.dataset.frame = String(meta.n);
        img.dataset.trial = String(meta.trial);
        framesShown += 1;
        img.dataset.shown = String(framesShown);
        if (trial && trial.trial === meta.trial) send({ type: "shown", n: meta.n });
      };
      img.src = reader.result;
    };
    reader.readAsDataURL(blob.slice(4, blob.size, "image/jpeg"));
  }

  function showScreen(which) {
    $("lab-task").hidden = which !== "instructions";
    $("lab-trial").hidden = which !== "trial" && which !== "next";
    $("lab-next").hidden = which !== "next";
  }

  function paragraphs(element, text) {
    element.textContent = "";
    for (const part of String(text || "").split(/\n\s*\n/)) {
      if (!part.trim()) continue;
      const p = document.createElement("p");
      p.textContent = part.trim();
      element.appendChild(p);
    }
  }

  function handle(message) {
    switch (message.type) {
      case "session":
        resuming = false;
        if (message.token) remember({ participant: message.participant, token: message.token });
        $("lab-welcome").hidden = true;
        $("lab-run").hidden = false;
        send({ type: "ready" });
        break;
      case "instructions":
        trial = null;
        showError("");
        $("lab-feedback").textContent = "";
        $("lab-progress").textContent = "Before trial " + message.trial + " of " + message.of;
        $("lab-task-title").textContent = "Instructions for the next task";
        paragraphs($("lab-task-text"), message.instructions);
        showScreen("instructions");
        setMode("instructions");
        $("lab-ack").focus();
        break;
      case "trial":
        trial = message;
        document.body.dataset.trial = String(message.trial);
        showError("");
        $("lab-feedback").textContent = "";
        $("lab-progress").textContent = (message.practice ? "Practice trial" : "Trial") + " " + message.trial + " of " + message.of;
        paragraphs($("lab-instructions"), message.first_of_task || message.practice ? message.instructions : "");
        $("lab-distance").hidden = message.kind !== "distance";
        $("lab-keys").hidden = message.kind === "distance";
        showScreen("trial");
        setMode("trial");
        if (message.kind === "distance") {
          $("lab-cm").value = "";
          $("lab-cm").max = String(message.answer.max);
          $("lab-cm").focus();
        }
        break;
      case "frame":
        expectFrame = message;
        break;
      case "saved":
        trial = null;
        showError("");
        $("lab-distance").hidden = true;
        $("lab-keys").hidden = true;
        $("lab-feedback").textContent = message.practice ? "Practice: you were " + message.error_cm.toFixed(1) + " cm off." : "";
        if (!message.completed) {
          showScreen("next");
          setMode("next");
          $("lab-next").focus();
        }
        break;
      case "done":
        remember(null);
        setMode("done");
        $("lab-welcome").hidden = true;
        $("lab-run").hidden = true;
        $("lab-done").hidden = false;
        $("lab-thanks").textContent = message.thanks;
        socket.close();
        break;
      case "error":
        waiting = false;
        if (resuming) {
          // the stored participant cannot be resumed: start afresh
          resuming = false;
          remember(null);
          $("lab-start-error").textContent = message.message;
          $("lab-start-button").disabled = false;
          socket.close();
          return;
        }
        if (mode === "welcome") {
          $("lab-start-error").textContent = message.message;
          $("lab-start-button").disabled = false;
          socket.close();
          return;
        }
        showError(message.message);
        break;
    }
  }

  // a key that went down before the current screen appeared, or that the system repeats while it
  // is held, does nothing
  function fresh(event) {
    return !event.repeat && event.timeStamp >= screenSince;
  }

  window.addEventListener("keydown", (event) => {
    if (event.repeat) {
      event.preventDefault();
      event.stopImmediatePropagation();
    }
  }, true);

  function acknowledge() {
    if (mode !== "instructions" || waiting) return;
    waiting = true;
    send({ type: "acknowledge" });
  }

  function next() {
    if (mode !== "next" || waiting) return;
    waiting = true;
    send({ type: "ready" });
  }

  function answer(extra) {
    if (mode !== "trial" || !trial || waiting) return;
    releaseAll();
    waiting = true;
    send(Object.assign({ type: "answer", trial: trial.trial }, extra || {}));
  }

  // creates the participant over HTTP: {participant, token, trials}, or throws the server's sentence
  async function join(label) {
    const body = preview ? { label: label, preview: preview } : { label: label };
    const response = await fetch("/api/lab/" + encodeURIComponent(slug) + "/participants", {
      method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body),
    });
    let answer = null;
    try { answer = await response.json(); } catch (e) { answer = null; }
    if (!response.ok) throw new Error((answer && answer.error) || ("The server refused to start (" + response.status + ")."));
    return answer;
  }

  $("lab-start").addEventListener("submit", (event) => {
    event.preventDefault();
    const label = $("lab-label").value.trim();
    if (label === "") {
      $("lab-start-error").textContent = "The participant code is empty; type the code the experimenter gave you, then start.";
      return;
    }
    $("lab-start-error").textContent = "";
    $("lab-start-button").disabled = true;
    join(label).then((joined) => {
      remember({ participant: joined.participant, token: joined.token });
      connect({ type: "start", participant: joined.participant, token: joined.token });
    }).catch((error) => {
      $("lab-start-error").textContent = error.message;
      $("lab-start-button").disabled = false;
    });
  });

  $("lab-distance").addEventListener("submit", (event) => {
    event.preventDefault();
    if (!trial) return;
    const cm = Number($("lab-cm").value);
    if ($("lab-cm").value.trim() === "" || !Number.isFinite(cm)) {
      showError("Type the distance in cm as a number.");
      return;
    }
    answer({ cm: cm });
  });

  // clicks: keyboard activation of a focused button is handled by the keydown handler below
  $("lab-next").addEventListener("click", (event) => { if (event.detail !== 0) next(); });
  $("lab-ack").addEventListener("click", (event) => { if (event.detail !== 0) acknowledge(); });

  document.addEventListener("keydown", (event) => {
    if (mode === "welcome" || mode === "done") return;
    const activates = event.key === "Enter" || (event.key === " " && event.target && event.target.tagName === "BUTTON");
    if (mode === "instructions" || mode === "next") {
      if (!activates) return;
      event.preventDefault();
      if (!fresh(event)) return;
      if (mode === "instructions") acknowledge(); else next();
      return;
    }
    if (!trial) return;
    if (trial.kind === "distance") {
      if (event.key === "Enter" && !fresh(event)) event.preventDefault();
      return; // the form submits
    }
    if (trial.keys.indexOf(event.key) >= 0) {
      event.preventDefault();
      if (!event.repeat) hold(event.key);
    } else if (event.key === "Enter") {
      event.preventDefault();
      if (fresh(event)) answer();
    }
  });

  document.addEventListener("keyup", (event) => release(event.key));
  window.addEventListener("blur", releaseAll);

  // a reload or a reopened tab resumes this browser's participant
  let saved = null;
  try { saved = JSON.parse(localStorage.getItem(storageKey) || "null"); } catch (e) { saved = null; }
  if (saved && saved.participant && saved.token) {
    resuming = true;
    $("lab-start-button").disabled = true;
    connect({ type: "resume", participant: saved.participant, token: saved.token });
  }
})();
