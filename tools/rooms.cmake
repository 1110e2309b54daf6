# The rooms of tools/ and what each may include (tools/README.md; each room's README says the same
# in words; tools/room_graph.cmake, beside this file, holds the whole tree's rules). A room per
# program (its folder) and one library, report/, the rendering imucal, stationctl and stationweb
# share. tools/ may include every other top folder; nothing outside tools/ includes it. A program's
# room lists what its own files include (tools/package/ is data, no room).
imucal_room(tools/report     LIBRARY imucal_report
             MAY_INCLUDE db/history calib/core calib/sim calib/studies/fleet sequences)
imucal_room(tools/imucal     MAY_INCLUDE tools/report tools/altsim db/archive calib/core calib/effects calib/sim
                                         calib/ains calib/nlsq calib/legacy calib/checks calib/pipeline
                                         calib/diagnosis calib/studies/design calib/studies/paper sequences)
imucal_room(tools/stationctl MAY_INCLUDE tools/report station/config station/control station/daemon db/history
                                         db/archive db/fleet)
imucal_room(tools/stationd   MAY_INCLUDE station/daemon station/config db/history db/fleet)
imucal_room(tools/stationsim MAY_INCLUDE drivers/simulated drivers/imu db/archive calib/core calib/effects)
imucal_room(tools/stationweb MAY_INCLUDE tools/report station/control station/daemon db/history db/fleet calib/core)
imucal_room(tools/altsim     LIBRARY imucal_altsim MAY_INCLUDE sequences)
imucal_room(tools/fleetsim   LIBRARY imucal_fleetsim
             MAY_INCLUDE db/history calib/core calib/sim calib/ains calib/pipeline calib/studies/fleet sequences)

imucal_room_rule(ROOMS tools/altsim REACH_ONLY sequences
                 BECAUSE "altsim is an independent simulator: it shares no code with calib/ (ARCHITECTURE §8)")
