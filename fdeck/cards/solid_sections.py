"""The hexahedral formulations a solid section may name (`full`, `fbar`, `reduced`, `ans`, `ans_fbar`, `ans_tbar`);
their section card is `fdeck.deck.model.Section`, their elements `fdeck.physics.elements.hex8` (`ans`: `hex8_ans`,
`ans_fbar` and `ans_tbar`: `hex8_ans_fbar`)."""

from fdeck.registry import CardEntry, register_card

for _name, _doc in (("full", "2x2x2 Gauss integration"),
                    ("fbar", "F-bar / mean dilatation, 2x2x2 points with volume-averaged J"),
                    ("reduced", "one point, uniform gradient, Flanagan-Belytschko hourglass control"),
                    ("ans", "2x2x2 points, assumed natural shear strains (no shear locking in bending)"),
                    ("ans_fbar", "2x2x2 points, assumed natural shear strains and F-bar's volume-averaged J"),
                    ("ans_tbar", "2x2x2 points, assumed natural shear strains and a volume-averaged thickness stretch "
                                 "normal to the fibre plane")):
    register_card(CardEntry(_name, None, "formulation", description=_doc))
