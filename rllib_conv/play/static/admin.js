// The admin page: live counts per condition and the downloads, behind the admin token.
"use strict";

const $ = (id) => document.getElementById(id);
const REFRESH_MS = 2000;
let token = new URLSearchParams(location.search).get("token") || "";

async function status() {
  const res = await fetch("/api/admin/status", { headers: { Authorization: "Bearer " + token } });
  const data = await res.json().catch(() => null);
  if (!res.ok) {
    const err = new Error(data && data.error ? data.error : `The server answered ${res.status}.`);
    err.status = res.status;
    throw err;
  }
  return data;
}

function cellsOf(c) {
  const plays = c.kind === "agent" ? "agent" : "another participant";
  const name = c.name + (c.active ? "" : " (not assigned any more)");
  return [name, plays, c.waiting, c.playing, c.finished, c.ended, c.rooms, c.tries + c.moves, c.description];
}

function render(s) {
  document.body.dataset.phase = "ready";
  const total = s.conditions.reduce((n, c) => n + c.finished, 0);
  const refused = s.refused_resumes ? ` · ${s.refused_resumes} refused re-enrolment${s.refused_resumes === 1 ? "" : "s"} ` +
    `(a participant id sent without its session token${s.recent_refused.length ? ": latest " + s.recent_refused.slice(-5).join(", ") : ""})` : "";
  $("summary").textContent = `${s.game} study · ${s.participants} participants · ${total} finished · ${s.connected} connected now` + refused;
  const body = $("conditions").querySelector("tbody");
  body.replaceChildren(...s.conditions.map((c) => {
    const tr = document.createElement("tr");
    tr.dataset.condition = c.name;
    for (const value of cellsOf(c)) {
      const td = document.createElement("td");
      td.textContent = String(value);
      tr.append(td);
    }
    return tr;
  }));
  const q = "token=" + encodeURIComponent(token);
  const links = [[`/api/admin/export.csv?${q}`, `all tries (${s.game} CSV, the format rllib-conv report reads)`]];
  for (const c of s.conditions) links.push([`/api/admin/export.csv?${q}&condition=${encodeURIComponent(c.name)}`, `condition ${c.name} only`]);
  links.push([`/api/admin/participants.csv?${q}`, "participants and completion codes"]);
  $("downloads").replaceChildren(...links.map(([href, text]) => {
    const li = document.createElement("li");
    const a = document.createElement("a");
    a.href = href;
    a.textContent = text;
    li.append(a);
    return li;
  }));
}

async function refresh() {
  try {
    render(await status());
    $("error").hidden = true;
    $("login").hidden = true;
    $("dashboard").hidden = false;
  } catch (e) {
    $("error").textContent = e.message;
    $("error").hidden = false;
    if (e.status === 401 || e.status === 403) {
      document.body.dataset.phase = "login";
      $("summary").textContent = "Enter the admin token.";  // not "Loading…" beside the error
      $("login").hidden = false;
      $("dashboard").hidden = true;
      return;  // no polling with a wrong token
    }
  }
  setTimeout(refresh, REFRESH_MS);
}

$("login").onsubmit = (ev) => {
  ev.preventDefault();
  token = $("token").value.trim();
  history.replaceState(null, "", "/admin?token=" + encodeURIComponent(token));
  refresh();
};
if (token) refresh(); else { $("login").hidden = false; $("summary").textContent = "Enter the admin token."; }
