"""mlct: real-time text-to-motion generation with Motion Latent Consistency Training."""

__version__ = "0.1.0"
