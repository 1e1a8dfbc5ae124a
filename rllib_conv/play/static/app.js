// rllib-conv play: the page. Talks to the JSON API of rllib_conv/play/server.py and renders
// the room's view as the server sends it (the server decides what each player may see).
"use strict";

const $ = (id) => document.getElementById(id);
const session = { info: null, room: null, token: null, version: -1, poll: 0, errorVersion: null };
const CELLS = ["top-left", "top-right", "bottom-left", "bottom-right"];

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
    throw new Error("Cannot reach the server (" + e.message + "). Is `rllib-conv play` still running?");
  }
  let data = null;
  try { data = await res.json(); } catch (e) { /* not JSON: reported below */ }
  if (!res.ok || data === null) {
    throw new Error(data && data.error ? data.error : `The server answered ${res.status} ${res.statusText}.`);
  }
  return data;
}

// An error stays until the player acts again or the room moves on (then it is out of date).
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

// Every user action: clear the old error, show the new one if the request is refused.
async function guarded(action) {
  clearError();
  try { await action(); } catch (e) { showError(e.message); }
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// --- home page ------------------------------------------------------------------------
const RULES = {
  bandit: "Each try shows a context (A, B or C) and four arms; green arms carry a prize. You and your partner each " +
    "pick an arm without seeing the other's pick, and win the prize only if you both pick the same green arm. " +
    "Both picks are shown after every try. Five tries per context; first the Train task, then the Test task.",
  blocks: "P1 (red) sees the goal grid, P2 (blue) does not. Moves alternate, P1 first, six moves in all: place your " +
    "block on a cell (it moves there, pushing out whatever was on that cell), remove it, or pass. Each block on its goal " +
    "cell at the end scores 10 points. The goal is shown to both once the game is over.",
};

async function init() {
  let info;
  try {
    info = await api("GET", "/api/info");
  } catch (e) {
    showError(e.message);
    return;
  }
  session.info = info;
  $("title").textContent = info.game === "bandit" ? "Collaborative bandit" : "Block placing";
  $("subtitle").textContent = info.game === "bandit"
    ? "The user study of “On the Critical Role of Conventions in Adaptive Human-AI Collaboration”"
    : (info.new_task ? "The 2x2 block placing game (new task: red goes on a cell that is empty in the goal)" : "The 2x2 block placing game");
  $("rules").textContent = RULES[info.game];
  $("agent-card").hidden = !info.agent;
  if (info.agent) {
    $("agent-desc").textContent = "Agent: " + info.agent_description + ". It adapts to you as you play.";
    const box = $("seat-choice");
    const preferred = 3 - info.ego_seat;  // the seat opposite the trained ego's
    info.seats.forEach((name, i) => {
      const label = document.createElement("label");
      const input = document.createElement("input");
      input.type = "radio";
      input.name = "seat";
      input.value = String(i + 1);
      input.checked = i + 1 === preferred;
      label.append(input, " " + name);
      box.append(label);
    });
  }
  $("start-agent").onclick = () => guarded(async () => {
    const seat = Number(document.querySelector("input[name=seat]:checked").value);
    const r = await api("POST", "/api/rooms", { mode: "agent", seat });
    enter(r.room, r.token, r.state);
  });
  $("create-room").onclick = () => guarded(async () => {
    const r = await api("POST", "/api/rooms", { mode: "human" });
    enter(r.room, r.token, r.state);
  });
  $("join-form").onsubmit = (ev) => {
    ev.preventDefault();
    guarded(() => joinRoom($("join-code").value));
  };
  const saved = new URLSearchParams(location.hash.slice(1));
  if (saved.get("room") && saved.get("token")) {
    enter(saved.get("room"), saved.get("token"), null);  // a reload keeps the seat
  } else {
    show("lobby");
  }
}

async function joinRoom(code) {
  code = String(code).trim().toUpperCase();
  if (!code) throw new Error("Type the room code your partner gave you.");
  const r = await api("POST", `/api/rooms/${encodeURIComponent(code)}/join`, {});
  enter(r.room, r.token, r.state);
}

function show(which) {
  $("lobby").hidden = which !== "lobby";
  $("game").hidden = which !== "game";
}

function enter(room, token, state) {
  session.room = room;
  session.token = token;
  session.version = -1;
  history.replaceState(null, "", `#room=${room}&token=${encodeURIComponent(token)}`);
  show("game");
  if (state) render(state);
  session.poll += 1;
  pollLoop(session.poll);
}

// Long polling: the server answers when the room changes (or after a while with no change).
async function pollLoop(generation) {
  while (generation === session.poll) {
    try {
      const s = await api("GET", `/api/rooms/${session.room}/state?token=${encodeURIComponent(session.token)}&since=${session.version}`);
      if (generation !== session.poll) return;
      render(s);
      if (s.phase === "finished") return;
    } catch (e) {
      showError(e.message);
      await sleep(1500);
    }
  }
}

async function sendMove(payload) {
  await guarded(async () => {
    const s = await api("POST", `/api/rooms/${session.room}/move`, { token: session.token, ...payload });
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
  document.body.dataset.phase = s.phase;
  document.body.dataset.played = String(s.played);
  document.body.dataset.version = String(s.version);
  $("room-code").textContent = s.room;
  $("you").textContent = s.game === "bandit" ? `Player ${s.you}` : `P${s.you} (${s.colour})`;
  $("partner").textContent = s.partner === "agent" ? "the agent" : s.partner === "person" ? "another person" : "not joined yet";
  $("status").textContent = s.status;
  // Once the session is over only the outcome and the history remain on the page.
  const over = s.phase === "finished";
  $("bandit").hidden = s.game !== "bandit" || over;
  $("blocks").hidden = s.game !== "blocks" || over;
  if (over && !$("history-box").dataset.opened) {
    $("history-box").open = true;
    $("history-box").dataset.opened = "1";
  }
  if (s.game === "bandit") renderBandit(s); else renderBlocks(s);
}

function renderBandit(s) {
  $("where").textContent = s.task ? `${s.task_label} · context ${s.context} · try ${s.try} of ${s.tries}` : "";
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
    const task = l.task === "train" ? "Train" : "Test";
    last.textContent = `Last try (${task} task, context ${l.context}, try ${l.try}): you pulled arm ${l.you}, ` +
      `${partnerName(s)} pulled arm ${l.partner}: ${l.prize > 0 ? "prize " + l.prize + "!" : "no prize."}`;
    last.className = "last" + (l.prize > 0 ? " win" : "");
  } else {
    last.textContent = "No try played yet.";
    last.className = "last";
  }
  const rows = s.history.map((h) => `<tr><td>${h.task === "train" ? "Train" : "Test"}</td><td>${h.context}</td><td>${h.try}</td><td>${h.you}</td><td>${h.partner}</td><td>${h.prize}</td></tr>`);
  $("history").innerHTML = "<tr><th>task</th><th>context</th><th>try</th><th>your arm</th><th>partner's arm</th><th>prize</th></tr>" + rows.join("");
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
window.play = { session, sendMove, joinRoom: (code) => guarded(() => joinRoom(code)) };
init();
