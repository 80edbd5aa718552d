"""copdea-fem: vibro-acoustic FE and reduced models of circular out-of-plane DEAs.

Pipeline (see DESIGN notes): study -> geometry/mesh -> prestress -> linearised
operators -> eigen step -> modes -> outputs; reduced model and diagnosis on top.
"""

__version__ = "0.1.0"
