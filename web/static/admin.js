// Admin study page: open/close the study, optional auto-refresh, preview links (made and
// revoked), and exclude / include / delete of participants. The admin cookie authenticates;
// changes also send X-Requested-With, which the server requires of cookie-authenticated changes.
"use strict";

(function () {
  const slug = document.body.dataset.study;
  const toggle = document.getElementById("toggle-open");
  if (toggle) {
    toggle.addEventListener("click", async () => {
      const open = toggle.dataset.open === "true";
      toggle.disabled = true;
      const response = await fetch("/api/admin/studies/" + encodeURIComponent(slug) + (open ? "/close" : "/open"), {
        method: "POST", headers: { "X-Requested-With": "mrstudy" }, credentials: "same-origin",
      });
      if (response.ok) location.reload();
      else { toggle.disabled = false; alert("The change failed (" + response.status + ")."); }
    });
  }
  // POSTs or DELETEs with the admin cookie; resolves to the JSON answer, throws its error sentence.
  async function change(method, url, body) {
    const headers = { "X-Requested-With": "mrstudy" };
    if (body !== undefined) headers["Content-Type"] = "application/json";
    const response = await fetch(url, {
      method, headers, credentials: "same-origin", body: body === undefined ? undefined : JSON.stringify(body),
    });
    let answer = null;
    try { answer = await response.json(); } catch (_) { answer = null; }
    if (!response.ok) throw new Error((answer && answer.error) || ("The change failed (" + response.status + ")."));
    return answer;
  }
  const problem = document.getElementById("participants-error");
  const showProblem = (message) => { if (problem) { problem.textContent = message; problem.hidden = false; } else alert(message); };

  const preview = document.getElementById("preview");
  if (preview) {
    preview.addEventListener("click", async () => {
      preview.disabled = true;
      try {
        const answer = await change("POST", "/api/admin/studies/" + encodeURIComponent(slug) + "/preview");
        const link = document.getElementById("preview-url");
        link.href = answer.url;
        link.textContent = new URL(answer.url, location.href).href;
        document.getElementById("preview-expiry").textContent =
          " (valid until " + new Date(answer.expires_at).toLocaleString() + ")";
        document.getElementById("preview-link").hidden = false;
        document.getElementById("previews-revoked").hidden = true;
        window.open(answer.url, "_blank", "noopener");
      } catch (error) {
        showProblem(error.message);
      } finally {
        preview.disabled = false;
      }
    });
  }

  // every preview link of the study stops working; pilots who joined keep their runs
  const revoke = document.getElementById("revoke-previews");
  if (revoke) {
    revoke.addEventListener("click", async () => {
      if (!confirm("Revoke every preview link of this study? Pilots who joined keep their runs.")) return;
      revoke.disabled = true;
      try {
        const answer = await change("DELETE", "/api/admin/studies/" + encodeURIComponent(slug) + "/preview");
        const note = document.getElementById("previews-revoked");
        note.textContent = answer.revoked === 1 ? "1 preview link revoked." : answer.revoked + " preview links revoked.";
        note.hidden = false;
        document.getElementById("preview-link").hidden = true;
      } catch (error) {
        showProblem(error.message);
      } finally {
        revoke.disabled = false;
      }
    });
  }

  document.querySelectorAll("tr[data-participant] button[data-action]").forEach((button) => {
    button.addEventListener("click", async () => {
      const row = button.closest("tr");
      const id = row.dataset.participant;
      const label = row.querySelector("td").textContent.trim();
      const base = "/api/admin/participants/" + encodeURIComponent(id);
      const action = button.dataset.action;
      try {
        if (action === "exclude") {
          const reason = prompt("Why is " + label + " excluded? (kept with the exclusion)");
          if (reason === null) return;
          if (reason.trim() === "") { showProblem("Excluding a participant needs a reason."); return; }
          button.disabled = true;
          await change("POST", base + "/exclude", { reason: reason.trim() });
        } else if (action === "include") {
          button.disabled = true;
          await change("POST", base + "/include");
        } else if (action === "delete") {
          if (!confirm("Delete every datum of " + label + " (responses, schedule, demographics, external ids)? This cannot be undone.")) return;
          button.disabled = true;
          await change("DELETE", base);
        }
        location.reload();
      } catch (error) {
        button.disabled = false;
        showProblem(error.message);
      }
    });
  });

  const refresh = document.getElementById("auto-refresh");
  if (refresh) {
    refresh.checked = sessionStorage.getItem("mrstudy:auto-refresh") === "1";
    const schedule = () => { if (refresh.checked) setTimeout(() => { if (refresh.checked) location.reload(); }, 15000); };
    refresh.addEventListener("change", () => {
      sessionStorage.setItem("mrstudy:auto-refresh", refresh.checked ? "1" : "0");
      schedule();
    });
    schedule();
  }
})();
