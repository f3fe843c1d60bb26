"""urident: dynamic parameter identification for Universal Robots arms."""

__version__ = "0.1.0"
