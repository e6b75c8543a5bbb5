// The operator console's link and safety state (inlined before console.js): what an operator must
// be able to trust. The state badge follows the server's status messages on the telemetry
// WebSocket (server/status_stream.hpp: on every change, and a heartbeat every 0.5 s), never a
// guess: when no message came for kLostAfterMs, or the socket closed, a red banner says the link
// is lost and since when, and the badge says the state is unknown. SAFE and TRIPPED latch on
// screen with their reason until the operator acknowledges them. ABORT that cannot be delivered
// says so, and retries every second until the server answers, then says when it did.
// For tests: body data-link (live | lost), data-state, data-latched (safe | tripped | ""),
// data-abort (idle | sending | not-delivered | delivered | answered).
"use strict";
window.hilLink = function hilLink({ $, body, api, ApiRefusal, showMessage, clearMessages, onState }) {
  const kLostAfterMs = 1500;  // three heartbeats missed
  const kAbortRetryMs = 1000;
  const kAbortTimeoutMs = 3000;  // an answer slower than this counts as none (a hung server)
  let lastMessageAt = Date.now();  // of the last message on the stream (at first: the page's load)
  let everHeard = false;
  let open = false;
  let lostSince = 0;       // when the link was found lost (0: live)
  let state = "unknown";
  let lastStatus = null;
  const clock = (ms) => new Date(ms).toISOString().slice(11, 19);
  body.dataset.link = "connecting";
  body.dataset.latched = "";
  body.dataset.abort = "idle";

  function setBadge(s) {
    const st = $("state");
    st.textContent = s === "unknown" ? "state unknown" : s;
    st.className = "state " + s;
    body.dataset.state = s;
  }

  // ---- the link --------------------------------------------------------------------------------
  function heard() {
    lastMessageAt = Date.now();
    everHeard = true;
    if (lostSince) {
      const was = lostSince;
      lostSince = 0;
      $("link-lost").hidden = true;
      // What the lost link made (failed fetches, refusals) is stale now; an abort's answer is not
      // (it may come before the stream's first message): it stays, the restored link said after it.
      const msg = $("message");
      const kept = !msg.hidden && /^abort (answered|delivered) at /.test(msg.textContent) ? msg.textContent + " · " : "";
      clearMessages();
      showMessage(kept + "link to the server restored at " + clock(Date.now()) + " (lost at " + clock(was) + ")", true);
    }
    body.dataset.link = "live";
    $("conn").textContent = "link: live";
  }
  function opened() {
    open = true;
  }
  function closed() {
    open = false;
    check();
  }
  function check() {
    const now = Date.now();
    const silentMs = now - lastMessageAt;
    if (silentMs < kLostAfterMs && (open || !everHeard)) return;  // live, or still connecting after the load
    if (!lostSince) {
      lostSince = now;
      setBadge("unknown");
      onState("unknown", null);
    }
    body.dataset.link = "lost";
    $("conn").textContent = "link: lost";
    const banner = $("link-lost");
    banner.hidden = false;
    banner.textContent = "LINK LOST: no message from the server for " +
      (silentMs / 1000).toFixed(1) + " s (" + (everHeard ? "last at " : "since the page loaded at ") + clock(lastMessageAt) + ")" +
      ". What this page shows may be stale; commands may not arrive. Reconnecting every second. " +
      "If the motor must stop now, use the bench's emergency stop.";
  }
  setInterval(check, 200);

  // ---- the state and its latch -------------------------------------------------------------------
  function latch(kind, reason, run) {
    const box = $("latch");
    box.className = "latch " + kind;
    $("latch-text").textContent = (kind === "tripped" ? "TRIPPED" : "SAFE STATE") + (run ? " in " + run : "") + ": " +
      (reason || "no reason given") + " (at " + clock(Date.now()) + ")";
    box.hidden = false;
    body.dataset.latched = kind;
    body.dataset.latchedReason = reason || "";
  }
  $("latch-ack").addEventListener("click", () => {
    $("latch").hidden = true;
    body.dataset.latched = "";
  });

  // A status message of the stream (status_stream.hpp).
  function status(m) {
    lastStatus = m;
    const s = String(m.state || "unknown");
    if ((s === "safe" || s === "tripped") && (body.dataset.latched !== s || body.dataset.latchedReason !== (m.reason || "")))
      latch(s, m.reason, m.run);
    if (s !== state) {
      state = s;
      setBadge(s);
    }
    onState(s, m);
  }
  // A run ended: an abort or a trip ends it through the safe state, however briefly it was held.
  function runEnd(m) {
    if (!m.trip) return;
    const kind = m.trip === "operator abort" ? "safe" : "tripped";  // an abort is commanded; the rest are interlocks
    if (body.dataset.latched === kind && body.dataset.latchedReason === (m.reason || "")) return;
    latch(kind, m.reason, m.run);
  }

  // ---- ABORT: delivered, answered, or said not to be -------------------------------------------
  let abortTries = 0;
  let abortTimer = null;
  async function abort(reason) {
    if (body.dataset.abort === "sending") return;
    clearTimeout(abortTimer);
    abortTimer = null;
    if (body.dataset.abort !== "not-delivered") abortTries = 0;
    ++abortTries;
    body.dataset.abort = "sending";
    $("abort").textContent = "ABORT (sending…)";
    const controller = new AbortController();
    const timer = setTimeout(() => controller.abort(), kAbortTimeoutMs);
    try {
      const reply = await api("POST", "/api/abort", { reason }, controller.signal);
      body.dataset.abort = "delivered";
      showMessage("abort delivered at " + clock(Date.now()) + (abortTries > 1 ? " (attempt " + abortTries + ")" : "") + ": " +
        reply.reason + (reply.note ? " (" + reply.note + ")" : ""), true);  // clears itself: the latch keeps what matters
    } catch (e) {
      if (e instanceof ApiRefusal) {
        body.dataset.abort = "answered";
        showMessage("abort answered at " + clock(Date.now()) + (abortTries > 1 ? " (attempt " + abortTries + ")" : "") +
          ": refused (" + e.status + ") " + e.message, e.status === 409);
      } else {
        body.dataset.abort = "not-delivered";
        showMessage("abort NOT delivered (attempt " + abortTries + ", " + clock(Date.now()) + ": " +
          (e && e.name === "AbortError" ? "no answer within " + kAbortTimeoutMs / 1000 + " s" : "the server is unreachable") +
          "). Retrying every second until the server answers; if the motor must stop now, use the bench's emergency stop.",
        false, true);
        abortTimer = setTimeout(() => abort(reason), kAbortRetryMs);
      }
    } finally {
      clearTimeout(timer);
      $("abort").textContent = body.dataset.abort === "not-delivered" ? "ABORT (retrying)" : "ABORT";
      onState(state, lastStatus);
    }
  }

  return { heard, opened, closed, status, runEnd, abort, live: () => !lostSince && open, state: () => state,
    aborting: () => body.dataset.abort === "sending" || body.dataset.abort === "not-delivered" };
};
