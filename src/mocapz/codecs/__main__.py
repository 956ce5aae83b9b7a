"""``python -m mocapz.codecs > docs/options.md``: the option reference of every registered codec."""

from mocapz.codecs import all_codecs
from mocapz.codecs.options import options_markdown

print(options_markdown(all_codecs()), end="")
