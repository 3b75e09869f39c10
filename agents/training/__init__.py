"""Training: stable-baselines3 through the native batch, Ray RLlib, imitation of the planner
(DAgger), the hyperparameter files and the callbacks."""
