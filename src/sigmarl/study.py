"""The ablation study's fixed vocabulary: models, their observation presets, the test scenarios."""

from __future__ import annotations

# Model name -> observation preset (conf/obs/<preset>.yaml).
MODELS: dict[str, str] = {
    "M0": "full",
    "M1": "no_ego_view",
    "M2": "no_vertices",
    "M3": "no_distance_to_agents",
    "M4": "no_distance_to_boundaries",
    "M5": "no_distance_to_center_line",
}
PRESET_TO_MODEL = {preset: model for model, preset in MODELS.items()}

# Scenario name -> (map config name, number of agents), study.md section 3.
SCENARIOS: dict[str, tuple[str, int]] = {
    "CPM": ("cpm", 15),
    "Intersection": ("intersection", 6),
    "On-Ramp": ("on_ramp", 8),
    "Roundabout": ("roundabout", 8),
}

# Columns of one evaluation row: one (model, seed, scenario, simulation).
# Collision rates are fractions of environment steps (0..1); the report shows percent.
METRIC_COLUMNS = ["CR_AA", "CR_AL", "CR_total", "CD", "AS"]  # CD in real centimetres, AS in m/s
ROW_KEYS = ["model", "obs", "seed", "scenario", "simulation"]
