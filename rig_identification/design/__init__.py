"""Know before you shake: the experiment design (planned runs, the fast screen, the search) and
random test rigs. Layer 3."""
