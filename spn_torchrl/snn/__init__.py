"""The spiking policy network: neuron dynamics (neurons), surrogate spike derivatives (surrogate) and the
population and trainable SPNs (policies). Knows nothing of envs, evaluation or the GA."""
