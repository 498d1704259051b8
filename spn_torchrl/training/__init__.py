"""The training loops: the GA as tensor operations (ga), a GA run (evolve) and a PPO run (ppo)."""
