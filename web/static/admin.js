// Admin study page: open/close the study, optional auto-refresh. The admin cookie authenticates;
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
