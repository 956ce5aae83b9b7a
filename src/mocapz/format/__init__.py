"""Bytes on disk: the ``.mcz`` container framing, the layout header (skeleton or marker set), the entropy
coder and integer packing the codecs share. Nothing here knows a codec's internals."""
