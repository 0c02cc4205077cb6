"""Traffic environment: a batched VMAS scenario (dynamics, observation, reward, collisions, resets)."""
