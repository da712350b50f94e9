"""JSON schema of the deck, for editors (yaml-language-server) and for the committed schemas/ file."""

from fdeck.deck.model import Deck


def deck_schema() -> dict:
    s = Deck.model_json_schema()
    s["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    s["title"] = "fdeck deck"
    return s
