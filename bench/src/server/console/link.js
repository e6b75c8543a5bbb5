// The operator console's link and safety state (inlined before console.js): what an operator must
// be able to trust. The state badge follows the server's status messages on the telemetry
// WebSocket (server/status_stream.hpp: on every change, and a heartbeat every 0.5 s), never a
// guess: when no message came for kLostAfterMs, or the socket closed, a red banner says the link
// is lost and since when, and the badge says the state is unknown. SAFE and TRIPPED latch on
// screen with their reason until the operator acknowledges them. ABORT that cannot be delivered
// says so, and retries every second until the server answers, then says when it did (an answer
// that there was nothing to abort is not a success). With no run under way the badge says how the
// last run ended (the status's last_run, also after a restart): SAFE after an abort, TRIPPED after
// an interlock, INTERRUPTED when a server died during it, else IDLE. A latch belongs to its run:
// another run's start marks it "previous run".
// For tests: body data-link (live | lost), data-state (the server's), data-badge (what the badge
// says), data-latched (safe | tripped | ""), data-latched-run (its run folder), data-latched-previous
// ("1" once another run started), data-abort (idle | sending | not-delivered | delivered | answered),
// data-abort-status (the HTTP status of the last answer).
"use strict";
window.hilLink = function hilLink({ $, body, api, ApiRefusal, showMessage, clearMessages, onState }) {
  const W = window.hilWords;
  const kLostAfterMs = 1500;  // three heartbeats missed
  const kAbortRetryMs = 1000;
  const kAbortTimeoutMs = 3000;  // an answer slower than this counts as none (a hung server)
  let lastMessageAt = Date.now();  // of the last message on the stream (at first: the page's load)
  let everHeard = false;
  let open = false;
  let lostSince = 0;       // when the link was found lost (0: live)
  let state = "unknown";
  let lastStatus = null;
  let lastRun = null;  // the status's last_run: how the last run ended
  let badgeKey = "";
  const clock = W.clock;
  body.dataset.link = "connecting";
  body.dataset.latched = "";
  body.dataset.abort = "idle";

  // The badge: the server's state, and while idle how the last run ended.
  function badgeOf(s) {
    if (s !== "idle" || !lastRun) return { cls: s, text: s === "unknown" ? "state unknown" : s, title: "" };
    const how = "no run under way; " + W.ended(lastRun);
    if (lastRun.outcome === "aborted") {
      const commanded = !lastRun.trip || lastRun.trip === "operator abort";
      return { cls: commanded ? "safe" : "tripped", text: commanded ? "safe" : "tripped", title: how + " (it ended in its safe state)" };
    }
    if (lastRun.outcome === "interrupted") return { cls: "interrupted", text: "interrupted", title: how };
    if (lastRun.outcome === "error") return { cls: "tripped", text: "error", title: how };
    return { cls: "idle", text: "idle", title: how };
  }
  function setBadge(s) {
    const b = badgeOf(s);
    const key = s + "|" + b.text + "|" + b.title;
    body.dataset.state = s;
    if (key === badgeKey) return;
    badgeKey = key;
    const st = $("state");
    st.textContent = b.text;
    st.className = "state " + b.cls;
    st.title = b.title;
    body.dataset.badge = b.text;
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
      const keptKind = kept ? msg.dataset.kind : "ok";
      clearMessages();
      showMessage(kept + "link to the server restored at " + clock(Date.now()) + " (lost at " + clock(was) + ")", keptKind === "warn" ? "warn" : keptKind !== "bad",
        false, !!kept);
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
  let latchText = "";
  function latch(kind, reason, run, dir, campaign) {
    const box = $("latch");
    box.className = "latch " + kind;
    latchText = (kind === "tripped" ? "TRIPPED" : "SAFE STATE") + (run ? " in " + W.run(run) + (campaign ? " of " + campaign : "") : "") + ": " +
      (reason || "no reason given") + " (at " + clock(Date.now()) + ")";
    $("latch-text").textContent = latchText;
    box.hidden = false;
    body.dataset.latched = kind;
    body.dataset.latchedReason = reason || "";
    body.dataset.latchedRun = dir || "";
    body.dataset.latchedPrevious = "";
  }
  const latchedHere = (kind, reason, dir) => body.dataset.latched === kind && body.dataset.latchedReason === (reason || "") &&
    (!dir || !body.dataset.latchedRun || body.dataset.latchedRun === dir);
  // Another run started: a latch still on screen is the previous run's, and says so.
  function newRun(dir) {
    if (!body.dataset.latched || !dir || body.dataset.latchedRun === dir || body.dataset.latchedPrevious) return;
    body.dataset.latchedPrevious = "1";
    $("latch").classList.add("previous");
    $("latch-text").textContent = "Previous run: " + latchText;
  }
  $("latch-ack").addEventListener("click", () => {
    $("latch").hidden = true;
    body.dataset.latched = "";
    body.dataset.latchedRun = "";
    body.dataset.latchedPrevious = "";
  });

  // A status message of the stream (status_stream.hpp).
  function status(m) {
    lastStatus = m;
    if (m.last_run !== undefined) lastRun = m.last_run;
    const s = String(m.state || "unknown");
    if (s !== "idle" && m.run_dir) newRun(m.run_dir);
    if ((s === "safe" || s === "tripped") && !latchedHere(s, m.reason, m.run_dir)) latch(s, m.reason, m.run, m.run_dir, m.campaign);
    state = s;
    setBadge(s);
    onState(s, m);
  }
  // A run ended: an abort or a trip ends it through the safe state, however briefly it was held.
  function runEnd(m) {
    if (!m.trip) return;
    const kind = m.trip === "operator abort" ? "safe" : "tripped";  // an abort is commanded; the rest are interlocks
    if (latchedHere(kind, m.reason, m.dir)) return;
    latch(kind, m.reason, m.run, m.dir, m.campaign);
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
      body.dataset.abortStatus = "200";
      showMessage("abort delivered at " + clock(Date.now()) + (abortTries > 1 ? " (attempt " + abortTries + ")" : "") + ": " +
        reply.reason + (reply.note ? " (" + reply.note + ")" : ""), true, false, true);  // clears itself: the latch keeps what matters
    } catch (e) {
      if (e instanceof ApiRefusal) {
        // 409: no run was under way to abort (it had ended, or a restarted server has none): this
        // abort did nothing, which is not a success; the header says how the run ended.
        body.dataset.abort = "answered";
        body.dataset.abortStatus = String(e.status);
        const none = e.status === 409;
        showMessage("abort answered at " + clock(Date.now()) + (abortTries > 1 ? " (attempt " + abortTries + ")" : "") + ": " +
          (none ? "not carried out: the server has no run under way (" + e.message + ")" +
            (lastRun ? "; the last run: " + W.ended(lastRun) : "") : "refused (" + e.status + ") " + e.message), none ? "warn" : false, false, true);
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

  return { heard, opened, closed, status, runEnd, newRun, abort, live: () => !lostSince && open, state: () => state, lastRun: () => lastRun,
    aborting: () => body.dataset.abort === "sending" || body.dataset.abort === "not-delivered" };
};
