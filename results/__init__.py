"""rpud.results: the end-to-end run, geometry -> modes -> A0 -> impacts -> kinetic energy."""
