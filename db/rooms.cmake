# The rooms of db/ and what each may include (db/README.md; each room's README says the same in
# words; tools/room_graph.cmake holds the whole tree's rules). One static library per room, linked
# only to the rooms listed here (db/CMakeLists.txt derives the link lines from this graph).
#
# db/ may include calib/ and sequences/, never drivers/, station/ or tools/. The archive reads and
# writes files: it uses calib's types (unit files, the diagnosis' JSON) and calib/input, which builds
# a run's calibration input from the series it reads, and never the simulator. The history stores
# runs and their archives; the fleet store implements the history's repository over PostgreSQL.
imucal_room(db/archive LIBRARY imucal_archive MAY_INCLUDE calib/core calib/effects calib/input calib/diagnosis sequences)
imucal_room(db/history LIBRARY imucal_history MAY_INCLUDE db/archive calib/core calib/checks)
imucal_room(db/fleet   LIBRARY imucal_fleet   MAY_INCLUDE db/history db/archive calib/core)

imucal_room_rule(ROOMS db/archive db/history db/fleet NEVER_REACH calib/sim
                 BECAUSE "the archive and the history read and store runs, they do not simulate them (issue #47)")
