// The participants' page: consent, instructions, play, completion code. Talks to the JSON API
// of rllib_conv/play/app.py; the server decides what each player may see, the page renders it.
"use strict";

const $ = (id) => document.getElementById(id);
const session = { info: null, participant: null, token: null, version: -1, socket: null, errorVersion: null, view: null };
const CELLS = ["top-left", "top-right", "bottom-left", "bottom-right"];
// Where recruitment platforms put the participant's id in the study link.
const ID_PARAMS = ["participant", "PROLIFIC_PID", "workerId"];
const STORE_KEY = "rllib-conv-study";
// The ids the server accepts (rllib_conv/play/study.py PARTICIPANT_ID).
const VALID_ID = /^[A-Za-z0-9._-]{1,64}$/;
const BAD_LINK = "This study link is incomplete or damaged, so we cannot tell who you are. Please go back to the " +
  "study platform (for example Prolific) and open the study from there again. If this keeps happening, please " +
  "contact the researcher. Nothing has been recorded.";
const PART = { train: "Part 1", test: "Part 2" };

// --- talking to the server ------------------------------------------------------------
async function api(method, path, body) {
  const opts = { method, headers: {} };
  if (body !== undefined) {
    opts.headers["Content-Type"] = "application/json";
    opts.body = JSON.stringify(body);
  }
  let res;
  try {
    res = await fetch(path, opts);
  } catch (e) {
    throw new Error("Cannot reach the study server (" + e.message + "). Please try again in a moment.");
  }
  let data = null;
  try { data = await res.json(); } catch (e) { /* not JSON: reported below */ }
  if (!res.ok || data === null) {
    const err = new Error(data && data.error ? data.error : `The server answered ${res.status} ${res.statusText}.`);
    err.status = res.status;
    throw err;
  }
  return data;
}

// An error stays until the player acts again or the session moves on (then it is out of date).
function showError(message) {
  const box = $("error");
  box.textContent = message;
  box.hidden = false;
  session.errorVersion = session.version;
}

function clearError() {
  $("error").hidden = true;
  $("error").textContent = "";
  session.errorVersion = null;
}

async function guarded(action) {
  clearError();
  try { await action(); } catch (e) { showError(e.message); }
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

function show(which) {
  for (const id of ["consent", "instructions", "game", "bad-link"]) $(id).hidden = id !== which;
}

// A participant id the server would refuse: say so in plain words, instead of a technical error after consent.
function badLink() {
  $("bad-link-text").textContent = BAD_LINK;
  document.body.dataset.phase = "bad_link";
  show("bad-link");
}

// --- consent, instructions, enrolment ---------------------------------------------------
const RULES = {
  bandit: "Each try shows one of three situations (A, B or C) and four arms; green arms carry a prize. You and your partner each " +
    "pick an arm without seeing the other's pick, and win the prize only if you both pick the same green arm. " +
    "Both picks are shown after every try. Five tries per situation. The game has two parts; in Part 2 " +
    "the green arms change.",
  blocks: "P1 (red) sees the goal grid, P2 (blue) does not. Moves alternate, P1 first, six moves in all: place your " +
    "block on a cell (it moves there, pushing out whatever was on that cell), remove it, or pass. Each block on its goal " +
    "cell at the end scores 10 points. The goal is shown to both once the game is over.",
};

function urlParticipant() {
  const params = new URLSearchParams(location.search);
  for (const name of ID_PARAMS) {
    if (params.get(name)) return params.get(name);
  }
  return null;
}

function saved() {
  try { return JSON.parse(localStorage.getItem(STORE_KEY) || "null"); } catch (e) { return null; }
}

function save(participant, token) {
  try { localStorage.setItem(STORE_KEY, JSON.stringify({ participant, token })); } catch (e) { /* private mode: resume by id only */ }
}

async function init() {
  let info;
  try {
    info = await api("GET", "/api/info");
  } catch (e) {
    showError(e.message);
    return;
  }
  session.info = info;
  $("subtitle").textContent = info.game === "bandit" ? "Pick the same prize as your partner." : "Build the goal grid with your partner.";
  const consent = $("consent-text");
  consent.replaceChildren(...info.consent.split(/\n\s*\n/).map((text) => {
    const p = document.createElement("p");
    p.textContent = text;
    return p;
  }));
  $("rules").textContent = RULES[info.game];
  $("agree").onchange = () => { $("to-instructions").disabled = !$("agree").checked; };
  $("to-instructions").onclick = () => show("instructions");
  $("start").onclick = () => guarded(enrol);

  // A page reloaded (or reopened) in the same browser resumes without asking again.
  const wanted = urlParticipant();
  if (wanted !== null && !VALID_ID.test(wanted)) { badLink(); return; }
  const mine = saved();
  if (mine && mine.token && (!wanted || wanted === mine.participant)) {
    try {
      const view = await api("GET", `/api/session?token=${encodeURIComponent(mine.token)}`);
      enter(mine.participant, mine.token, view);
      return;
    } catch (e) {
      if (e.status !== 403) { showError(e.message); return; }
    }
  }
  show("consent");
}

async function enrol() {
  const body = { consent: $("agree").checked };
  const id = urlParticipant();
  if (id) body.participant = id;
  // Re-enrolling an id resumes only with the token its first enrolment gave this browser.
  const mine = saved();
  if (id && mine && mine.participant === id && mine.token) body.token = mine.token;
  let r;
  try {
    r = await api("POST", "/api/participants", body);
  } catch (e) {
    if (e.status === 400 && /^participant must be/.test(e.message)) { badLink(); return; }
    throw e;
  }
  save(r.participant, r.token);
  enter(r.participant, r.token, r.view);
}

function enter(participant, token, view) {
  session.participant = participant;
  session.token = token;
  session.version = -1;
  show("game");
  render(view);
  listen();
}

// --- live views over a WebSocket ---------------------------------------------------------
// The server pushes the view after every change; a lost connection is reopened (the server
// may have restarted) and the first message brings the page up to date.
function listen() {
  let delay = 500;
  const open = () => {
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    const ws = new WebSocket(`${scheme}://${location.host}/api/live?token=${encodeURIComponent(session.token)}`);
    session.socket = ws;
    ws.onopen = () => { delay = 500; $("offline").hidden = true; };
    ws.onmessage = (ev) => render(JSON.parse(ev.data));
    ws.onclose = () => {
      if (session.view && (session.view.phase === "finished" || session.view.phase === "ended")) return;
      $("offline").hidden = false;
      setTimeout(open, delay);
      delay = Math.min(delay * 2, 5000);
    };
  };
  open();
}

async function sendMove(payload) {
  await guarded(async () => {
    const step = session.view ? session.view.step : 0;
    const s = await api("POST", "/api/move", { token: session.token, step, ...payload });
    render(s);
  });
}

// --- rendering ------------------------------------------------------------------------
function partnerName(s) {
  return s.partner === "agent" ? "the agent" : s.partner === "person" ? "your partner" : "nobody yet";
}

function render(s) {
  if (s.version < session.version) return;  // an older answer overtaken by a newer one
  if (session.errorVersion !== null && s.version > session.errorVersion) clearError();
  session.version = s.version;
  session.view = s;
  document.body.dataset.phase = s.phase;
  document.body.dataset.played = String(s.played);
  document.body.dataset.version = String(s.version);
  const seated = s.you !== undefined;
  const over = s.phase === "finished" || s.phase === "ended";
  // Nobody to name once a session ended before it had a partner: no "waiting · partner: not yet found".
  $("room-line").hidden = !seated && over;
  $("you").textContent = !seated ? "waiting" : s.game === "bandit" ? `Player ${s.you}` : `P${s.you} (${s.colour})`;
  $("partner").textContent = s.partner === "agent" ? "an AI agent" : s.partner === "person" ? "another participant" : "not yet found";
  $("status").textContent = s.status;
  $("done").hidden = !s.completion_code;
  $("completion-code").textContent = s.completion_code || "";
  $("bandit").hidden = s.game !== "bandit" || over || !seated;
  $("blocks").hidden = s.game !== "blocks" || over || !seated;
  $("score").hidden = !seated;
  $("last").hidden = !seated;
  $("history-box").hidden = !seated;
  if (over && !$("history-box").dataset.opened) {
    $("history-box").open = true;
    $("history-box").dataset.opened = "1";
  }
  if (!seated) return;
  if (s.game === "bandit") renderBandit(s); else renderBlocks(s);
}

function renderBandit(s) {
  $("where").textContent = s.task ? `${s.task_label} · situation ${s.context} · try ${s.try} of ${s.tries}` : "";
  const arms = $("arms");
  arms.replaceChildren();
  for (const a of s.arms) {
    const b = document.createElement("button");
    b.type = "button";
    b.className = "arm" + (a.prize > 0 ? " good" : "") + (s.your_choice === a.arm ? " chosen" : "");
    b.dataset.arm = String(a.arm);
    b.disabled = s.phase !== "choose";
    b.innerHTML = `Arm ${a.arm}<small>${a.prize > 0 ? "prize " + a.prize : "no prize"}</small>`;
    b.onclick = () => sendMove({ arm: a.arm });
    arms.append(b);
  }
  $("score").textContent = `Score: ${s.score} · ${s.played} of ${s.total} tries played`;
  const last = $("last");
  if (s.last) {
    const l = s.last;
    last.textContent = `Last try (${PART[l.task]}, situation ${l.context}, try ${l.try}): you pulled arm ${l.you}, ` +
      `${partnerName(s)} pulled arm ${l.partner}: ${l.prize > 0 ? "prize " + l.prize + "!" : "no prize."}`;
    last.className = "last" + (l.prize > 0 ? " win" : "");
  } else {
    last.textContent = "No try played yet.";
    last.className = "last";
  }
  const rows = s.history.map((h) => `<tr><td>${PART[h.task]}</td><td>${h.context}</td><td>${h.try}</td><td>${h.you}</td><td>${h.partner}</td><td>${h.prize}</td></tr>`);
  $("history").innerHTML = "<tr><th>part</th><th>situation</th><th>try</th><th>your arm</th><th>partner's arm</th><th>prize</th></tr>" + rows.join("");
}

// A grid cell: a button on the working grid, a plain box elsewhere (goal, past games).
function cell(code, label, clickable = false) {
  const el = document.createElement(clickable ? "button" : "span");
  if (clickable) el.type = "button";
  el.className = "cell" + (code === 1 ? " red" : code === 2 ? " blue" : code === 3 ? " hidden" : "");
  el.textContent = label;
  return el;
}

function miniGrid(codes) {
  const g = document.createElement("span");
  g.className = "grid small";
  codes.forEach((c) => g.append(cell(c, "")));
  return g;
}

function renderBlocks(s) {
  if (s.error) showError(s.error);
  const mine = s.phase === "your_turn";
  const goal = $("goal");
  goal.replaceChildren();
  const board = $("board");
  board.replaceChildren();
  if (s.grid) {
    for (let i = 0; i < 4; i++) {
      const g = cell(s.goal ? s.goal[i] : 3, s.goal ? "" : "?");
      g.title = s.goal ? CELLS[i] : "hidden from P2 until the game ends";
      goal.append(g);
      const c = cell(s.grid[i], CELLS[i], true);
      c.dataset.cell = String(i);
      c.disabled = !mine;
      c.onclick = () => sendMove({ action: i });
      board.append(c);
    }
  }
  $("remove").disabled = !mine;
  $("remove").onclick = () => sendMove({ action: 4 });
  $("pass").disabled = !mine;
  $("pass").onclick = () => sendMove({ action: 5 });
  const who = (p) => (p === s.you ? " (you)" : s.partner === "agent" ? " (agent)" : " (partner)");
  $("moves").innerHTML = (s.moves || []).map((m) => `<li>${m.text}${who(m.player)}</li>`).join("");
  $("score").textContent = `Score: ${s.score} points · ${s.played} of ${s.games} games played` + (s.phase === "finished" ? "" : ` · game ${s.game_no}`);
  const last = $("last");
  last.replaceChildren();
  if (s.last) {
    const l = s.last;
    last.append(`Last game (${l.game}): goal`, miniGrid(l.goal), "final grid", miniGrid(l.grid), `score ${l.score}. Moves: ` + l.moves.map((m) => m.text).join(", "));
    last.className = "last" + (l.score >= 20 ? " win" : "");
  } else {
    last.textContent = "No game finished yet.";
    last.className = "last";
  }
  const rows = s.results.map((r) => `<tr><td>${r.game}</td><td>${r.score}</td><td>${r.moves.map((m) => m.text).join(", ")}</td></tr>`);
  $("history").innerHTML = "<tr><th>game</th><th>score</th><th>moves</th></tr>" + rows.join("");
}

// For scripted tests and the curious: the same calls the buttons make.
window.play = { session, sendMove, api };
init();
