"""People play the paper's games in a browser, with a trained ego or with each other: a study server.

`rllib-conv play [RUN] [--agent NAME=RUN ...] [--conditions agent,human]` serves a study
(docs/play.md): participants arrive with an id in the URL, consent, read the instructions,
are assigned to a condition (balanced), play, and get a completion code. In an agent
condition the partner is the trained ego's task module (the rules) times a partner
module for this person learnt between tries (`agent.py`); in the human condition two
waiting participants are paired. The bandit session is the paper's study: Train task
then Test task, contexts A, B, C, five tries each. Every try is committed to SQLite
before it is acknowledged; `rllib-conv play export DB` writes the user-study CSV.

Modules, bottom up: `agent` (the adapting agent and its hindsight targets), `ego_run` (a
trained ego read from its trial folder as the agent's prior), `store` (the SQLite
database), `room`, `bandit_room`, `blocks_room` (the games' state machines: turns, steps,
what each player sees, replay), `conditions` (conditions and settings from the command
line), `study` (participants, assignment, pairing, timeouts, completion codes, restore),
`export` (the CSV exports), `limits` (request size and time limits), `app` (the Starlette
app: pages, JSON API, WebSocket, admin API), `server` (uvicorn on one socket), `command`
(the CLI's `play` arguments), `simulated` (scripted participants for rehearsals, the load
benchmark and the fault tests), `static/` (the participants' and the admin page).
"""
