"""rpud.impact: the free-mass collision model of the RPUD percussive system."""
