"""People play the paper's games in a browser, with a trained ego or with each other.

`rllib-conv play [RUN] [--game bandit|blocks] [--port 8000]` serves a page on 127.0.0.1:

- human + agent: a person plays with the trained ego in RUN (choosing the seat). The agent
  is the ego's task module (the rules) times a partner module for this person that it
  learns between tries (`agent.py` documents the rule).
- human + human: one browser creates a room, another joins with its code; the only
  channel between them is the game, as in the paper's user study.

The bandit session is the paper's study: Train task then Test task, contexts A, B, C,
five tries each, both picks revealed after each try. Sessions are recorded under
`--out` (`recording.py`): bandit sessions in the exact format of
`analysis/data/user_study.csv`, one row per pair, task, context and try.

Modules: `agent` (the adapting agent and its hindsight targets), `ego_run` (a trained ego
read from its trial folder as the agent's prior), `room`, `bandit_room`, `blocks_room` (the
game state machines, turn checks, what each player sees), `lobby` (creating and finding
rooms), `recording` (atomic CSV appends), `server` (http.server JSON API + static page in
`static/`), `command` (the CLI's `play` arguments).
"""
