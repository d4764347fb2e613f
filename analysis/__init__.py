"""Pure analysis: model, simulator, identification, dynamics tools, discrepancy analysis."""
