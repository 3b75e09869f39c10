"""``python -m agents.rl_from_reward``: the command lives in
:mod:`agents.commands.rl_from_reward`."""

from agents.commands.rl_from_reward import main

if __name__ == "__main__":
    raise SystemExit(main())
