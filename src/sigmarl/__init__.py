"""sigmarl: the SigmaRL observation-design ablation study, end to end."""

__version__ = "0.1.0"
