"""The stages of ``commission``, one module each; every stage returns one report section."""
