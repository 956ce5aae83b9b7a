"""The motion model every other layer speaks: :class:`Skeleton`, :class:`Motion` (skeletal channels),
:class:`MarkerMotion` (marker clouds), forward kinematics and length units. Nothing here reads files or
knows codecs."""
