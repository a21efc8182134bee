"""Localization: motion model, Monte Carlo and grid Markov localization, entropy and novelty filters."""
