"""The parts of the generated DBC that no gearbox description changes: the header, the J1939 input messages
the sensor decodes, the attribute definitions, GBX_STATUS and GBX_DM1 (can_dbc.generate puts the per-component
frames between them). Each constant is the DBC's lines, in file order."""

from __future__ import annotations

#: The header, the nodes and the J1939 input messages (EEC1 ... TP_DT), each message followed by a blank line.
HEAD = (
    'VERSION "gearbox-vsensor 1"',
    "",
    "",
    "NS_ :",
    "\tNS_DESC_",
    "\tCM_",
    "\tBA_DEF_",
    "\tBA_",
    "\tVAL_",
    "\tCAT_DEF_",
    "\tCAT_",
    "\tFILTER",
    "\tBA_DEF_DEF_",
    "\tEV_DATA_",
    "\tENVVAR_DATA_",
    "\tSGTYPE_",
    "\tSGTYPE_VAL_",
    "\tBA_DEF_SGTYPE_",
    "\tBA_SGTYPE_",
    "\tSIG_TYPE_REF_",
    "\tVAL_TABLE_",
    "\tSIG_GROUP_",
    "\tSIG_VALTYPE_",
    "\tSIGTYPE_VALTYPE_",
    "\tBO_TX_BU_",
    "\tBA_DEF_REL_",
    "\tBA_REL_",
    "\tBA_DEF_SGTYPE_REL_",
    "\tBA_SGTYPE_REL_",
    "\tSG_MUL_VAL_",
    "",
    "BS_:",
    "",
    "BU_: Engine Transmission Retarder GearboxVSensor RigLogger",
    "",
    "",
    "BO_ 2364539904 EEC1: 8 Engine",
    ' SG_ ActualEngPercentTorque : 16|8@1+ (1,-125) [-125|125] "%" GearboxVSensor',
    ' SG_ EngSpeed : 24|16@1+ (0.125,0) [0|8031.875] "rpm" GearboxVSensor',
    "",
    "BO_ 2565866755 ETC2: 8 Transmission",
    ' SG_ TransCurrentGear : 24|8@1+ (1,-125) [-125|125] "" GearboxVSensor',
    "",
    "BO_ 2566846467 TRF1: 8 Transmission",
    ' SG_ TransOilLevel : 8|8@1+ (0.4,0) [0|100] "%" Vector__XXX',
    ' SG_ TransOilTemp : 32|16@1+ (0.03125,-273) [-273|1734.96875] "degC" GearboxVSensor',
    ' SG_ TransOilLevelMeasStatus : 60|4@1+ (1,0) [0|15] "" Vector__XXX',
    "",
    "BO_ 2566843904 ET1: 8 Engine",
    ' SG_ EngCoolantTemp : 0|8@1+ (1,-40) [-40|210] "degC" GearboxVSensor',
    "",
    "BO_ 2566845696 AMB: 8 Engine",
    ' SG_ AmbientAirTemp : 24|16@1+ (0.03125,-273) [-273|1734.96875] "degC" GearboxVSensor',
    "",
    "BO_ 2566844672 CCVS1: 8 Engine",
    ' SG_ WheelBasedVehicleSpeed : 8|16@1+ (0.00390625,0) [0|250.99609375] "km/h" GearboxVSensor',
    "",
    "BO_ 2565865488 ERC1: 8 Retarder",
    ' SG_ ActualRetarderPercentTorque : 8|8@1+ (1,-125) [-125|125] "%" GearboxVSensor',
    "",
    "BO_ 2632777472 TP_CM: 8 Engine",
    ' SG_ TP_CM_Control M : 0|8@1+ (1,0) [0|255] "" GearboxVSensor',
    ' SG_ TP_BAM_MessageSize m32 : 8|16@1+ (1,0) [9|1785] "byte" GearboxVSensor',
    ' SG_ TP_BAM_NumPackets m32 : 24|8@1+ (1,0) [2|255] "" GearboxVSensor',
    ' SG_ TP_RTS_MessageSize m16 : 8|16@1+ (1,0) [9|1785] "byte" GearboxVSensor',
    ' SG_ TP_RTS_NumPackets m16 : 24|8@1+ (1,0) [2|255] "" GearboxVSensor',
    ' SG_ TP_RTS_MaxPacketsPerCTS m16 : 32|8@1+ (1,0) [1|255] "" GearboxVSensor',
    ' SG_ TP_CTS_NumPackets m17 : 8|8@1+ (1,0) [0|255] "" GearboxVSensor',
    ' SG_ TP_CTS_NextPacket m17 : 16|8@1+ (1,0) [1|255] "" GearboxVSensor',
    ' SG_ TP_EOMA_MessageSize m19 : 8|16@1+ (1,0) [9|1785] "byte" GearboxVSensor',
    ' SG_ TP_EOMA_NumPackets m19 : 24|8@1+ (1,0) [2|255] "" GearboxVSensor',
    ' SG_ TP_Abort_Reason m255 : 8|8@1+ (1,0) [0|255] "" GearboxVSensor',
    ' SG_ TP_CM_PGN : 40|24@1+ (1,0) [0|262143] "" GearboxVSensor',
    "",
    "BO_ 2632711936 TP_DT: 8 Engine",
    ' SG_ TP_DT_SequenceNumber : 0|8@1+ (1,0) [1|255] "" GearboxVSensor',
    ' SG_ TP_DT_Data : 8|56@1+ (1,0) [0|72057594037927935] "" GearboxVSensor',
    "",
)

#: Comments on the nodes and the input messages and signals.
INPUT_COMMENTS = (
    'CM_ BU_ Engine "Engine #1 (J1939 source address 0x00).";',
    'CM_ BU_ Transmission "Transmission #1 (J1939 source address 0x03).";',
    'CM_ BU_ Retarder "Driveline retarder (J1939 source address 0x10).";',
    ('CM_ BU_ GearboxVSensor "The gearbox virtual temperature sensor (default source address 0xE5, configurable).";'),
    'CM_ BU_ RigLogger "Test-rig thermocouple logger (source address 0xF0).";',
    (
        'CM_ BO_ 2364539904 "Electronic Engine Controller 1, PGN 61444 (0xF004), input from the engine '
        '(default source address 0x00).";'
    ),
    (
        'CM_ SG_ 2364539904 ActualEngPercentTorque "SPN 513 actual engine percent torque, byte 3; Nm = '
        'percent / 100 x engine reference torque (EC1 SPN 544).";'
    ),
    (
        'CM_ SG_ 2364539904 EngSpeed "SPN 190 engine speed, bytes 4-5; raw 0xFE00-0xFEFF error, '
        '0xFF00-0xFFFF not available.";'
    ),
    (
        'CM_ BO_ 2565866755 "Electronic Transmission Controller 2, PGN 61445 (0xF005), input from the '
        'transmission (default source address 0x03).";'
    ),
    (
        'CM_ SG_ 2565866755 TransCurrentGear "SPN 523 transmission current gear, byte 4: negative '
        'reverse, 0 neutral, positive forward; 251 park.";'
    ),
    (
        'CM_ BO_ 2566846467 "Transmission Fluids 1, PGN 65272 (0xFEF8), input from the transmission '
        '(default source address 0x03).";'
    ),
    (
        "CM_ SG_ 2566846467 TransOilLevel \"SPN 124 transmission oil level, byte 2: the sump's oil volume "
        "as a share of its nominal (maximum required) volume; not used by the onboard sensor, read by the"
        ' fleet health (gearbox-vsensor fleet --diagnose) when the truck sends it.";'
    ),
    'CM_ SG_ 2566846467 TransOilTemp "SPN 177 transmission oil temperature, bytes 5-6.";',
    (
        'CM_ SG_ 2566846467 TransOilLevelMeasStatus "SPN 3026 transmission oil level measurement status, '
        "byte 8 bits 5-8: 0 the conditions for a level reading are valid; 1-13 they are not (a settling "
        "timer, in gear, oil too cold or too hot, vehicle moving ...); 14 error; 15 not available. The "
        'fleet health counts a level (SPN 124) only with 0 or 15.";'
    ),
    (
        'CM_ BO_ 2566843904 "Engine Temperature 1, PGN 65262 (0xFEEE), input from the engine (default '
        'source address 0x00).";'
    ),
    'CM_ SG_ 2566843904 EngCoolantTemp "SPN 110 engine coolant temperature, byte 1.";',
    'CM_ BO_ 2566845696 "Ambient Conditions, PGN 65269 (0xFEF5), input (default source address 0x00).";',
    'CM_ SG_ 2566845696 AmbientAirTemp "SPN 171 ambient air temperature, bytes 4-5.";',
    ('CM_ BO_ 2566844672 "Cruise Control/Vehicle Speed 1, PGN 65265 (0xFEF1), input (default source address 0x00).";'),
    'CM_ SG_ 2566844672 WheelBasedVehicleSpeed "SPN 84 wheel-based vehicle speed, bytes 2-3.";',
    (
        'CM_ BO_ 2565865488 "Electronic Retarder Controller 1, PGN 61440 (0xF000), input from the '
        "driveline retarder (default source address 0x10); Nm = percent / 100 x the retarder's reference "
        "torque: RC (PGN 65249, SPN 556, by TP.BAM from the retarder's source address) once received, else "
        'the configured one ([can] retarder_reference_torque_nm).";'
    ),
    'CM_ SG_ 2565865488 ActualRetarderPercentTorque "SPN 520 actual retarder percent torque, byte 2.";',
    (
        'CM_ BO_ 2632777472 "Transport Protocol Connection Management, PGN 60416 (0xEC00), J1939-21, '
        "shown for the global destination 0xFF. The sensor reassembles EC1 (PGN 65251, 0xFEE3, longer "
        "than 8 bytes) and RC (PGN 65249, 0xFEE1, from the retarder) from a BAM (control byte 32) and the "
        "TP.DT packets that follow, then takes EC1's bytes 20-21 as SPN 544 engine reference torque and "
        "RC's bytes 17-18 as SPN 556 retarder reference torque (1 Nm/bit). This is done in code "
        "(can_dbc/decoder.py); "
        'a DBC cannot describe a reassembled message.";'
    ),
    'CM_ SG_ 2632777472 TP_CM_Control "Control byte: 16 RTS, 17 CTS, 19 EndOfMsgAck, 32 BAM, 255 Abort.";',
    'CM_ SG_ 2632777472 TP_BAM_MessageSize "BAM: total message size in bytes.";',
    'CM_ SG_ 2632777472 TP_BAM_NumPackets "BAM: total number of TP.DT packets.";',
    'CM_ SG_ 2632777472 TP_RTS_MessageSize "RTS: total message size in bytes.";',
    'CM_ SG_ 2632777472 TP_RTS_NumPackets "RTS: total number of packets.";',
    'CM_ SG_ 2632777472 TP_RTS_MaxPacketsPerCTS "RTS: maximum packets per CTS (255 no limit).";',
    'CM_ SG_ 2632777472 TP_CTS_NumPackets "CTS: number of packets that can be sent.";',
    'CM_ SG_ 2632777472 TP_CTS_NextPacket "CTS: next packet number to be sent.";',
    'CM_ SG_ 2632777472 TP_EOMA_MessageSize "EndOfMsgAck: total message size.";',
    'CM_ SG_ 2632777472 TP_EOMA_NumPackets "EndOfMsgAck: total number of packets.";',
    'CM_ SG_ 2632777472 TP_Abort_Reason "Connection abort reason.";',
    'CM_ SG_ 2632777472 TP_CM_PGN "PGN of the packeted message (65251 = 0xFEE3 = EC1 Engine Configuration 1).";',
    (
        'CM_ BO_ 2632711936 "Transport Protocol Data Transfer, PGN 60160 (0xEB00), J1939-21: 7 data bytes'
        " per packet, numbered 1..N. For EC1 the reassembled bytes 20-21 carry SPN 544 engine reference "
        'torque, 1 Nm/bit (reassembled in code).";'
    ),
    'CM_ SG_ 2632711936 TP_DT_SequenceNumber "Packet sequence number, 1..N.";',
    (
        'CM_ SG_ 2632711936 TP_DT_Data "7 bytes of the packeted message, little-endian; unused bytes of '
        'the last packet are 0xFF.";'
    ),
)

#: Attribute definitions and defaults, the database and node attributes, the input frames' attributes.
DEFINITIONS = (
    'BA_DEF_  "ProtocolType" STRING ;',
    'BA_DEF_  "BusType" STRING ;',
    'BA_DEF_ BU_  "NmStationAddress" HEX 0 255;',
    'BA_DEF_ BO_  "VFrameFormat" ENUM  "StandardCAN","ExtendedCAN","reserved","J1939PG";',
    'BA_DEF_ BO_  "GenMsgCycleTime" INT 0 65535;',
    'BA_DEF_ SG_  "SPN" INT 0 524287;',
    'BA_DEF_ SG_  "ComponentId" STRING ;',
    'BA_DEF_DEF_  "ProtocolType" "J1939";',
    'BA_DEF_DEF_  "BusType" "CAN";',
    'BA_DEF_DEF_  "NmStationAddress" 254;',
    'BA_DEF_DEF_  "VFrameFormat" "J1939PG";',
    'BA_DEF_DEF_  "GenMsgCycleTime" 0;',
    'BA_DEF_DEF_  "SPN" 0;',
    'BA_DEF_DEF_  "ComponentId" "";',
    'BA_ "ProtocolType" "J1939";',
    'BA_ "BusType" "CAN";',
    'BA_ "NmStationAddress" BU_ Engine 0;',
    'BA_ "NmStationAddress" BU_ Transmission 3;',
    'BA_ "NmStationAddress" BU_ Retarder 16;',
    'BA_ "NmStationAddress" BU_ GearboxVSensor 229;',
    'BA_ "NmStationAddress" BU_ RigLogger 240;',
    'BA_ "VFrameFormat" BO_ 2364539904 3;',
    'BA_ "GenMsgCycleTime" BO_ 2364539904 20;',
    'BA_ "VFrameFormat" BO_ 2565866755 3;',
    'BA_ "GenMsgCycleTime" BO_ 2565866755 100;',
    'BA_ "VFrameFormat" BO_ 2566846467 3;',
    'BA_ "GenMsgCycleTime" BO_ 2566846467 1000;',
    'BA_ "VFrameFormat" BO_ 2566843904 3;',
    'BA_ "GenMsgCycleTime" BO_ 2566843904 1000;',
    'BA_ "VFrameFormat" BO_ 2566845696 3;',
    'BA_ "GenMsgCycleTime" BO_ 2566845696 1000;',
    'BA_ "VFrameFormat" BO_ 2566844672 3;',
    'BA_ "GenMsgCycleTime" BO_ 2566844672 100;',
    'BA_ "VFrameFormat" BO_ 2565865488 3;',
    'BA_ "GenMsgCycleTime" BO_ 2565865488 100;',
    'BA_ "VFrameFormat" BO_ 2632777472 3;',
    'BA_ "VFrameFormat" BO_ 2632711936 3;',
)

#: The SPN attribute of each input signal.
INPUT_SPNS = (
    'BA_ "SPN" SG_ 2364539904 ActualEngPercentTorque 513;',
    'BA_ "SPN" SG_ 2364539904 EngSpeed 190;',
    'BA_ "SPN" SG_ 2565866755 TransCurrentGear 523;',
    'BA_ "SPN" SG_ 2566846467 TransOilLevel 124;',
    'BA_ "SPN" SG_ 2566846467 TransOilTemp 177;',
    'BA_ "SPN" SG_ 2566846467 TransOilLevelMeasStatus 3026;',
    'BA_ "SPN" SG_ 2566843904 EngCoolantTemp 110;',
    'BA_ "SPN" SG_ 2566845696 AmbientAirTemp 171;',
    'BA_ "SPN" SG_ 2566844672 WheelBasedVehicleSpeed 84;',
    'BA_ "SPN" SG_ 2565865488 ActualRetarderPercentTorque 520;',
)

#: The value tables of the input signals.
INPUT_VALUES = (
    'VAL_ 2364539904 ActualEngPercentTorque 254 "error" 255 "not available" ;',
    'VAL_ 2364539904 EngSpeed 65024 "error" 65535 "not available" ;',
    'VAL_ 2565866755 TransCurrentGear 251 "park" 254 "error" 255 "not available" ;',
    'VAL_ 2566846467 TransOilLevel 254 "error" 255 "not available" ;',
    'VAL_ 2566846467 TransOilTemp 65024 "error" 65535 "not available" ;',
    'VAL_ 2566846467 TransOilLevelMeasStatus 0 "conditions valid" 14 "error" 15 "not available" ;',
    'VAL_ 2566843904 EngCoolantTemp 254 "error" 255 "not available" ;',
    'VAL_ 2566845696 AmbientAirTemp 65024 "error" 65535 "not available" ;',
    'VAL_ 2566844672 WheelBasedVehicleSpeed 65024 "error" 65535 "not available" ;',
    'VAL_ 2565865488 ActualRetarderPercentTorque 254 "error" 255 "not available" ;',
    'VAL_ 2632777472 TP_CM_Control 16 "RTS" 17 "CTS" 19 "EndOfMsgAck" 32 "BAM" 255 "Abort" ;',
    (
        'VAL_ 2632777472 TP_Abort_Reason 1 "already in a session" 2 "resources needed elsewhere" 3 '
        '"timeout" 4 "CTS while transfer in progress" 5 "maximum retransmit request limit reached" 254 '
        '"error" 255 "not available" ;'
    ),
    'VAL_ 2632777472 TP_CM_PGN 65251 "EC1" 65226 "DM1" ;',
)

#: GBX_STATUS and GBX_DM1, each followed by a blank line (``{status_id}``: GBX_STATUS's frame id).
STATUS_MESSAGES = (
    "BO_ {status_id} GBX_STATUS: 8 GearboxVSensor",
    ' SG_ SpeedValid : 0|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ TorqueValid : 2|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ GearValid : 4|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ OilValid : 6|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ RefTorqueValid : 8|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ MaxWarnLevel : 10|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ DegradedMode : 12|4@1+ (1,0) [0|15] "" Vector__XXX',
    ' SG_ OilInnovation : 16|16@1+ (0.03125,-1000) [-1000|1007.96875] "degC" Vector__XXX',
    ' SG_ ModelOilTemp : 32|16@1+ (0.03125,-273) [-273|1734.96875] "degC" Vector__XXX',
    ' SG_ TimeBaseSuspect : 48|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ RollingCounter : 56|8@1+ (1,0) [0|255] "" Vector__XXX',
    "",
    "BO_ 2566834917 GBX_DM1: 8 GearboxVSensor",
    ' SG_ ProtectLampStatus : 0|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ AmberWarningLampStatus : 2|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ RedStopLampStatus : 4|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ MalfunctionIndLampStatus : 6|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ FlashProtectLamp : 8|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ FlashAmberWarningLamp : 10|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ FlashRedStopLamp : 12|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ FlashMalfunctionIndLamp : 14|2@1+ (1,0) [0|3] "" Vector__XXX',
    ' SG_ DTC1_SPN_Low : 16|16@1+ (1,0) [0|65535] "" Vector__XXX',
    ' SG_ DTC1_FMI : 32|5@1+ (1,0) [0|31] "" Vector__XXX',
    ' SG_ DTC1_SPN_High : 37|3@1+ (1,0) [0|7] "" Vector__XXX',
    ' SG_ DTC1_OccurrenceCount : 40|7@1+ (1,0) [0|127] "" Vector__XXX',
    ' SG_ DTC1_SPNConvMethod : 47|1@1+ (1,0) [0|1] "" Vector__XXX',
    "",
)

#: Comments on GBX_STATUS and GBX_DM1 (``{status_pgn}``: GBX_STATUS's PGN as ``65359 (0xFF4F)``).
STATUS_COMMENTS = (
    (
        'CM_ BO_ {status_id} "Virtual sensor status: input validity, degraded mode, oil innovation, model'
        " oil temperature, rolling counter; J1939 Proprietary B PGN {status_pgn}, priority 6, default "
        'source address 0xE5, 100 ms. Byte 7: TimeBaseSuspect in bits 0-1, the other bits sent as 1.";'
    ),
    'CM_ SG_ {status_id} SpeedValid "Input engine speed is fresh and valid: 0 no, 1 yes, 3 not available.";',
    'CM_ SG_ {status_id} TorqueValid "Input engine torque is fresh and valid: 0 no, 1 yes, 3 not available.";',
    'CM_ SG_ {status_id} GearValid "Input current gear is fresh and valid: 0 no, 1 yes, 3 not available.";',
    (
        'CM_ SG_ {status_id} OilValid "Input measured oil temperature is fresh and valid: 0 no, 1 yes, 3 '
        'not available.";'
    ),
    (
        'CM_ SG_ {status_id} RefTorqueValid "Input engine reference torque (EC1 or configured) is fresh '
        'and valid: 0 no, 1 yes, 3 not available.";'
    ),
    (
        'CM_ SG_ {status_id} MaxWarnLevel "Highest warning level over all published components (3 only '
        'when none is available).";'
    ),
    (
        'CM_ SG_ {status_id} DegradedMode "Operating mode: 0 normal, 1 oil model only, 2 inputs missing -'
        ' holding, 3 not initialised, 15 not available.";'
    ),
    (
        'CM_ SG_ {status_id} OilInnovation "Measured minus model oil temperature; 0xFFFF not available '
        '(no valid measurement or model).";'
    ),
    'CM_ SG_ {status_id} ModelOilTemp "Model oil (sump) temperature; 0xFFFF not available.";',
    (
        'CM_ SG_ {status_id} TimeBaseSuspect "Frame time not to be trusted: 1 = the input messages keep '
        "arriving several times faster or slower than their J1939 periods in frame time (a bus replayed "
        "faster or slower than real time whose frames are stamped on arrival), so every output is "
        "suspect; 3 = no such finding (a rate check can flag a wrong time base, never prove a right one)."
        ' 0 is not sent.";'
    ),
    'CM_ SG_ {status_id} RollingCounter "Incremented by one per transmission, wraps 255 -> 0.";',
    (
        'CM_ BO_ 2566834917 "J1939-73 DM1 active diagnostic trouble codes of the sensor, PGN 65226 '
        "(0xFECA), single frame, 1000 ms and on change; carries the most severe active component DTC: SPN"
        " = DTC1_SPN_Low + 65536 x DTC1_SPN_High = 520192 + published component index, FMI 16 warning, "
        'FMI 0 critical. No active DTC: SPN 0, FMI 0, OC 0. Bytes 7-8 0xFF.";'
    ),
    'CM_ SG_ 2566834917 ProtectLampStatus "Status of the protect lamp.";',
    'CM_ SG_ 2566834917 AmberWarningLampStatus "Status of the amber warning lamp.";',
    'CM_ SG_ 2566834917 RedStopLampStatus "Status of the red stop lamp.";',
    'CM_ SG_ 2566834917 MalfunctionIndLampStatus "Status of the MIL.";',
    'CM_ SG_ 2566834917 FlashProtectLamp "Flash state of the protect lamp.";',
    'CM_ SG_ 2566834917 FlashAmberWarningLamp "Flash state of the amber warning lamp.";',
    'CM_ SG_ 2566834917 FlashRedStopLamp "Flash state of the red stop lamp.";',
    'CM_ SG_ 2566834917 FlashMalfunctionIndLamp "Flash state of the MIL.";',
    (
        'CM_ SG_ 2566834917 DTC1_SPN_Low "DTC 1: SPN bits 1-16 (conversion method 4); SPN = DTC1_SPN_Low '
        "+ 65536 x DTC1_SPN_High = 520192 + published component index. SPN 0 (with FMI 0 and occurrence "
        'count 0): no active DTC.";'
    ),
    (
        'CM_ SG_ 2566834917 DTC1_FMI "DTC 1: failure mode identifier: 16 (above normal - moderately '
        "severe) for a warning, 0 (above normal - most severe) for critical, 9 (abnormal update rate) on "
        "the SPN of a drive input (190, 544, 513, 523) missing while no level can be evaluated. FMI 0 "
        "with SPN 0 is J1939's no active DTC.\";"
    ),
    (
        'CM_ SG_ 2566834917 DTC1_SPN_High "DTC 1: SPN bits 17-19 (7 for every component DTC of the '
        'sensor; 0 with DTC1_SPN_Low 0: no active DTC).";'
    ),
    ('CM_ SG_ 2566834917 DTC1_OccurrenceCount "DTC 1: occurrence count, 1..126; 0 no active DTC; 127 not available.";'),
    'CM_ SG_ 2566834917 DTC1_SPNConvMethod "DTC 1: SPN conversion method, always 0 (version 4).";',
)

#: The value tables of GBX_STATUS and GBX_DM1.
STATUS_VALUES = (
    'VAL_ {status_id} SpeedValid 0 "invalid" 1 "valid" 2 "error" 3 "not available" ;',
    'VAL_ {status_id} TorqueValid 0 "invalid" 1 "valid" 2 "error" 3 "not available" ;',
    'VAL_ {status_id} GearValid 0 "invalid" 1 "valid" 2 "error" 3 "not available" ;',
    'VAL_ {status_id} OilValid 0 "invalid" 1 "valid" 2 "error" 3 "not available" ;',
    'VAL_ {status_id} RefTorqueValid 0 "invalid" 1 "valid" 2 "error" 3 "not available" ;',
    'VAL_ {status_id} MaxWarnLevel 0 "normal" 1 "warning" 2 "critical" 3 "not available" ;',
    (
        'VAL_ {status_id} DegradedMode 0 "normal" 1 "oil model only" 2 "inputs missing - holding" 3 "not '
        'initialised" 15 "not available" ;'
    ),
    'VAL_ {status_id} OilInnovation 65535 "not available" ;',
    'VAL_ {status_id} ModelOilTemp 65535 "not available" ;',
    'VAL_ {status_id} TimeBaseSuspect 0 "no" 1 "suspect" 2 "error" 3 "no finding" ;',
    'VAL_ 2566834917 ProtectLampStatus 0 "off" 1 "on" 2 "reserved" 3 "not available" ;',
    'VAL_ 2566834917 AmberWarningLampStatus 0 "off" 1 "on" 2 "reserved" 3 "not available" ;',
    'VAL_ 2566834917 RedStopLampStatus 0 "off" 1 "on" 2 "reserved" 3 "not available" ;',
    'VAL_ 2566834917 MalfunctionIndLampStatus 0 "off" 1 "on" 2 "reserved" 3 "not available" ;',
    'VAL_ 2566834917 FlashProtectLamp 0 "slow flash" 1 "fast flash" 2 "reserved" 3 "do not flash" ;',
    'VAL_ 2566834917 FlashAmberWarningLamp 0 "slow flash" 1 "fast flash" 2 "reserved" 3 "do not flash" ;',
    'VAL_ 2566834917 FlashRedStopLamp 0 "slow flash" 1 "fast flash" 2 "reserved" 3 "do not flash" ;',
    'VAL_ 2566834917 FlashMalfunctionIndLamp 0 "slow flash" 1 "fast flash" 2 "reserved" 3 "do not flash" ;',
    (
        'VAL_ 2566834917 DTC1_FMI 0 "no active DTC if SPN = 0, else above normal - most severe '
        '(critical)" 9 "abnormal update rate (a drive input missing)" 16 "above normal - moderately '
        'severe (warning)" 31 "condition exists" ;'
    ),
    'VAL_ 2566834917 DTC1_OccurrenceCount 0 "no active DTC" 127 "not available" ;',
)
