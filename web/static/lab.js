// The lab task page: one WebSocket session (see studies/README.md, "The live WebSocket API").
// Keys go to the server as they are pressed; frames come back as a JSON "frame" message followed
// by a binary message (u32 frame number, big-endian, then the JPEG), shown in order.
(function () {
  "use strict";
  const slug = document.body.dataset.slug;
  const $ = (id) => document.getElementById(id);
  const storageKey = "mrstudy-lab-" + slug;
  let socket = null;
  let trial = null;
  let expectFrame = null;
  let framesShown = 0;

  function send(message) {
    if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(message));
  }

  function showError(text) {
    $("lab-error").textContent = text || "";
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
      const message = JSON.parse(event.data);
      handle(message);
    };
    socket.onclose = () => {
      if (!$("lab-done").hidden) return;
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
        framesShown += 1;
        img.dataset.shown = String(framesShown);
      };
      img.src = reader.result;
    };
    reader.readAsDataURL(blob.slice(4, blob.size, "image/jpeg"));
    $("lab-stats").textContent = "frame " + meta.n + ": " + meta.render_ms.toFixed(1) + " ms to render" +
      (meta.latency_ms !== null ? ", " + meta.latency_ms.toFixed(1) + " ms after the key" : "");
  }

  function handle(message) {
    switch (message.type) {
      case "session":
        if (message.token) {
          try { sessionStorage.setItem(storageKey, JSON.stringify({ participant: message.participant, token: message.token })); } catch (e) { /* private mode */ }
        }
        $("lab-welcome").hidden = true;
        $("lab-run").hidden = false;
        send({ type: "ready" });
        break;
      case "trial":
        trial = message;
        showError("");
        $("lab-feedback").textContent = "";
        $("lab-next").hidden = true;
        $("lab-progress").textContent = (message.practice ? "Practice trial" : "Trial") + " " + message.trial + " of " + message.of;
        $("lab-instructions").textContent = message.first_of_task || message.practice ? message.instructions : "";
        $("lab-distance").hidden = message.kind !== "distance";
        $("lab-keys").hidden = message.kind === "distance";
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
        $("lab-distance").hidden = true;
        $("lab-keys").hidden = true;
        if (message.practice) {
          $("lab-feedback").textContent = "Practice: you were " + message.error_cm.toFixed(1) + " cm off.";
        }
        if (!message.completed) {
          $("lab-next").hidden = false;
          $("lab-next").focus();
        }
        break;
      case "done":
        try { sessionStorage.removeItem(storageKey); } catch (e) { /* ignore */ }
        $("lab-run").hidden = true;
        $("lab-done").hidden = false;
        $("lab-thanks").textContent = message.thanks;
        socket.close();
        break;
      case "error":
        showError(message.message);
        break;
    }
  }

  $("lab-start").addEventListener("submit", (event) => {
    event.preventDefault();
    $("lab-start-button").disabled = true;
    connect({ type: "start", label: $("lab-label").value });
  });

  $("lab-distance").addEventListener("submit", (event) => {
    event.preventDefault();
    if (!trial) return;
    const cm = Number($("lab-cm").value);
    if ($("lab-cm").value.trim() === "" || !Number.isFinite(cm)) {
      showError("Type the distance in cm as a number.");
      return;
    }
    send({ type: "answer", trial: trial.trial, cm: cm });
  });

  $("lab-next").addEventListener("click", () => send({ type: "ready" }));

  document.addEventListener("keydown", (event) => {
    if (!trial || trial.kind === "distance") return;
    if (trial.keys.indexOf(event.key) >= 0) {
      event.preventDefault();
      send({ type: "key", key: event.key, t: performance.now() });
    } else if (event.key === "Enter") {
      event.preventDefault();
      send({ type: "answer", trial: trial.trial });
    }
  });

  // a reload resumes the participant of this tab
  let saved = null;
  try { saved = JSON.parse(sessionStorage.getItem(storageKey) || "null"); } catch (e) { saved = null; }
  if (saved && saved.participant && saved.token) {
    connect({ type: "resume", participant: saved.participant, token: saved.token });
  }
})();
