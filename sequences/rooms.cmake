# sequences/ is one room (sequences/README.md): the rotation sequences, their parser, validator and
# motion-profile generator. Every other top folder may include it; it includes nothing of ours
# (tools/room_graph.cmake holds the direction).
imucal_room(sequences LIBRARY imucal_sequences)
