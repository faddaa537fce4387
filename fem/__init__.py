"""rpud.fem: coupled piezo-elastic finite elements on scikit-fem."""
