"""Evaluation: test-mode rollouts of trained policies and the study metrics."""
