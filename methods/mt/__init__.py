"""The Multi-Triangulation of Williams et al. 2003."""
