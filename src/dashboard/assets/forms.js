// cliffwatch dashboard: tells the user when a form sent by htmx failed (htmx swaps only 2xx
// answers, so a refused acknowledgement would otherwise look like a click that did nothing).
// The message goes in as text, never as HTML.
(function () {
  "use strict";
  function message(xhr) {
    var text = (xhr && xhr.responseText) || "";
    try {
      var body = JSON.parse(text);
      if (body && body.error && body.error.message) text = body.error.message;
    } catch (e) { /* plain text */ }
    var status = xhr && xhr.status ? xhr.status + ": " : "";
    return status + (text || "the server did not answer");
  }
  function show(evt) {
    var elt = evt.detail && evt.detail.elt;
    var form = elt && (elt.closest ? elt.closest("form") : null);
    if (!form) return;
    var out = form.querySelector(".form-error");
    if (!out) {
      out = document.createElement("p");
      out.className = "error form-error";
      out.setAttribute("role", "alert");
      form.appendChild(out);
    }
    out.textContent = "Not done — " + message(evt.detail.xhr);
  }
  document.addEventListener("htmx:responseError", show);
  document.addEventListener("htmx:sendError", show);
})();
