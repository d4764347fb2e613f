"""Control panels: connection, shaker, recording and sweeps, status, replay, analysis."""
