/* pbcard_dpm.h: the pbcard DPM image (docs/DPM.md) and its SPI frames (docs/SPI.md).
 *
 * Generated from crates/dpm/src/dpm/layout.rs, spi.rs and spi/cyclic.rs. Do not edit:
 * DPM_DOC_WRITE=1 cargo test -p pbcard-dpm --lib --target x86_64-unknown-linux-gnu dpm::c_header
 *
 * Blocks: PBCARD_<BLOCK>_START (absolute) and _SIZE; PBCARD_<BLOCK>_<FIELD> is the offset
 * inside the block, PBCARD_<BLOCK>_<FIELD>_ADDR the absolute one, _SIZE its bytes. Every
 * multi-byte integer is big-endian. */
#ifndef PBCARD_DPM_H
#define PBCARD_DPM_H

/* ---- the image (docs/DPM.md) ---- */
#define PBCARD_DPM_MAGIC                              "PBDM"   /* HEADER.MAGIC */
#define PBCARD_DPM_LAYOUT_VERSION                     4u       /* HEADER.LAYOUT_VERSION */
#define PBCARD_DPM_IMAGE_SIZE                         752u     /* bytes in the image */
#define PBCARD_DPM_IMAGE_SIZE_V1                      192u     /* image size of that layout version */
#define PBCARD_DPM_IMAGE_SIZE_V2                      624u     /* image size of that layout version */
#define PBCARD_DPM_IMAGE_SIZE_V3                      728u     /* image size of that layout version */
#define PBCARD_DPM_IMAGE_SIZE_V4                      752u     /* image size of that layout version */
#define PBCARD_PD_CAPACITY                            64u      /* bytes of OUTPUTS / INPUTS DATA */
#define PBCARD_MBX_CAPACITY                           128u     /* bytes of mailbox VALUES */
#define PBCARD_EXT_DIAG_CAPACITY                      32u      /* bytes of DRIVE.EXT_DIAG */
#define PBCARD_EXTRA_WORDS                            16u      /* DRIVE_CMD / DRIVE_STATE extra words */
#define PBCARD_CARD_EVENT_COUNT                       8u       /* CARD.EVENTS counters */

/* HEADER.CAPABILITIES bits */
#define PBCARD_CAP_IDENT                              0x01u    /* capability */
#define PBCARD_CAP_CARD_EVENTS                        0x02u    /* capability */
#define PBCARD_CAP_DRIVE_REPORTS                      0x04u    /* capability */
#define PBCARD_CAP_CONFIG                             0x08u    /* capability */
#define PBCARD_CAP_MAILBOX                            0x10u    /* capability */
#define PBCARD_CAP_DRIVE_CMD                          0x20u    /* capability */
#define PBCARD_CAP_DRIVE_STATE                        0x40u    /* capability */
#define PBCARD_CAP_DEVICE                             0x80u    /* capability */

/* DRIVE_CMD.OPERATE_MODE / CONFIG.OPERATE_MODE codes */
#define PBCARD_OPERATE_MODE_UNKNOWN                   0u       /* operate mode */
#define PBCARD_OPERATE_MODE_PROFIDRIVE                1u       /* operate mode */
#define PBCARD_OPERATE_MODE_BYPASS                    2u       /* operate mode */
#define PBCARD_OPERATE_MODE_ECHO                      3u       /* operate mode */

/* HEADER (writer card, since v1): Magic, layout version, image size, capabilities. Written once when the image is created. */
#define PBCARD_HEADER_START                           0x000u   /* block start */
#define PBCARD_HEADER_SIZE                            16u      /* block length */
#define PBCARD_HEADER_EVENT_BIT                       0u       /* its bit in the pending-events bitmap */
#define PBCARD_HEADER_MAGIC                           0x00u    /* u8[4] */
#define PBCARD_HEADER_MAGIC_ADDR                      0x000u   /* absolute */
#define PBCARD_HEADER_MAGIC_SIZE                      4u       /* bytes */
#define PBCARD_HEADER_LAYOUT_VERSION                  0x04u    /* u16 */
#define PBCARD_HEADER_LAYOUT_VERSION_ADDR             0x004u   /* absolute */
#define PBCARD_HEADER_IMAGE_SIZE                      0x06u    /* u16 */
#define PBCARD_HEADER_IMAGE_SIZE_ADDR                 0x006u   /* absolute */
#define PBCARD_HEADER_CAPABILITIES                    0x08u    /* u32 */
#define PBCARD_HEADER_CAPABILITIES_ADDR               0x008u   /* absolute */
#define PBCARD_HEADER_CAPABILITIES_SIZE               4u       /* bytes */

/* STATUS (writer card, sequenced, since v1): Communication state, baud rate, addresses, telegram, DP state, counters. Written when it changes. */
#define PBCARD_STATUS_START                           0x010u   /* block start */
#define PBCARD_STATUS_SIZE                            32u      /* block length */
#define PBCARD_STATUS_EVENT_BIT                       1u       /* its bit in the pending-events bitmap */
#define PBCARD_STATUS_SEQ_HEAD                        0x00u    /* u16 */
#define PBCARD_STATUS_SEQ_HEAD_ADDR                   0x010u   /* absolute */
#define PBCARD_STATUS_COMM_STATE                      0x02u    /* u8 */
#define PBCARD_STATUS_COMM_STATE_ADDR                 0x012u   /* absolute */
#define PBCARD_STATUS_BAUD                            0x03u    /* u8 */
#define PBCARD_STATUS_BAUD_ADDR                       0x013u   /* absolute */
#define PBCARD_STATUS_STATION_ADDRESS                 0x04u    /* u8 */
#define PBCARD_STATUS_STATION_ADDRESS_ADDR            0x014u   /* absolute */
#define PBCARD_STATUS_MASTER_ADDRESS                  0x05u    /* u8 */
#define PBCARD_STATUS_MASTER_ADDRESS_ADDR             0x015u   /* absolute */
#define PBCARD_STATUS_TELEGRAM                        0x06u    /* u16 */
#define PBCARD_STATUS_TELEGRAM_ADDR                   0x016u   /* absolute */
#define PBCARD_STATUS_DP_STATE                        0x08u    /* u8 */
#define PBCARD_STATUS_DP_STATE_ADDR                   0x018u   /* absolute */
#define PBCARD_STATUS_FLAGS                           0x09u    /* u8 */
#define PBCARD_STATUS_FLAGS_ADDR                      0x019u   /* absolute */
#define PBCARD_STATUS_WATCHDOG_MS                     0x0Au    /* u16 */
#define PBCARD_STATUS_WATCHDOG_MS_ADDR                0x01Au   /* absolute */
#define PBCARD_STATUS_DATA_EXCHANGES                  0x0Cu    /* u32 */
#define PBCARD_STATUS_DATA_EXCHANGES_ADDR             0x01Cu   /* absolute */
#define PBCARD_STATUS_DATA_EXCHANGES_SIZE             4u       /* bytes */
#define PBCARD_STATUS_PRM_FAULTS                      0x10u    /* u16 */
#define PBCARD_STATUS_PRM_FAULTS_ADDR                 0x020u   /* absolute */
#define PBCARD_STATUS_CFG_FAULTS                      0x12u    /* u16 */
#define PBCARD_STATUS_CFG_FAULTS_ADDR                 0x022u   /* absolute */
#define PBCARD_STATUS_WATCHDOG_EXPIRIES               0x14u    /* u16 */
#define PBCARD_STATUS_WATCHDOG_EXPIRIES_ADDR          0x024u   /* absolute */
#define PBCARD_STATUS_CORRUPT_FRAMES                  0x16u    /* u16 */
#define PBCARD_STATUS_CORRUPT_FRAMES_ADDR             0x026u   /* absolute */
#define PBCARD_STATUS_SEQ_TAIL                        0x1Eu    /* u16 */
#define PBCARD_STATUS_SEQ_TAIL_ADDR                   0x02Eu   /* absolute */

/* OUTPUTS (writer card, sequenced, since v1): Process data master → drive. Written on every Data_Exchange and when its meaning changes. */
#define PBCARD_OUTPUTS_START                          0x030u   /* block start */
#define PBCARD_OUTPUTS_SIZE                           72u      /* block length */
#define PBCARD_OUTPUTS_EVENT_BIT                      2u       /* its bit in the pending-events bitmap */
#define PBCARD_OUTPUTS_SEQ_HEAD                       0x00u    /* u16 */
#define PBCARD_OUTPUTS_SEQ_HEAD_ADDR                  0x030u   /* absolute */
#define PBCARD_OUTPUTS_TELEGRAM                       0x02u    /* u16 */
#define PBCARD_OUTPUTS_TELEGRAM_ADDR                  0x032u   /* absolute */
#define PBCARD_OUTPUTS_LEN                            0x04u    /* u8 */
#define PBCARD_OUTPUTS_LEN_ADDR                       0x034u   /* absolute */
#define PBCARD_OUTPUTS_FLAGS                          0x05u    /* u8 */
#define PBCARD_OUTPUTS_FLAGS_ADDR                     0x035u   /* absolute */
#define PBCARD_OUTPUTS_DATA                           0x06u    /* u8[64] */
#define PBCARD_OUTPUTS_DATA_ADDR                      0x036u   /* absolute */
#define PBCARD_OUTPUTS_DATA_SIZE                      64u      /* bytes */
#define PBCARD_OUTPUTS_SEQ_TAIL                       0x46u    /* u16 */
#define PBCARD_OUTPUTS_SEQ_TAIL_ADDR                  0x076u   /* absolute */

/* INPUTS (writer host, sequenced, since v1): Process data drive → master (layout 1 / 2 hosts). The card serves an image written for the active telegram until the host first writes DRIVE_STATE; from then on the inputs are built from DRIVE_STATE and INPUTS is ignored. */
#define PBCARD_INPUTS_START                           0x078u   /* block start */
#define PBCARD_INPUTS_SIZE                            72u      /* block length */
#define PBCARD_INPUTS_EVENT_BIT                       3u       /* its bit in the pending-events bitmap */
#define PBCARD_INPUTS_SEQ_HEAD                        0x00u    /* u16 */
#define PBCARD_INPUTS_SEQ_HEAD_ADDR                   0x078u   /* absolute */
#define PBCARD_INPUTS_TELEGRAM                        0x02u    /* u16 */
#define PBCARD_INPUTS_TELEGRAM_ADDR                   0x07Au   /* absolute */
#define PBCARD_INPUTS_LEN                             0x04u    /* u8 */
#define PBCARD_INPUTS_LEN_ADDR                        0x07Cu   /* absolute */
#define PBCARD_INPUTS_FLAGS                           0x05u    /* u8 */
#define PBCARD_INPUTS_FLAGS_ADDR                      0x07Du   /* absolute */
#define PBCARD_INPUTS_DATA                            0x06u    /* u8[64] */
#define PBCARD_INPUTS_DATA_ADDR                       0x07Eu   /* absolute */
#define PBCARD_INPUTS_DATA_SIZE                       64u      /* bytes */
#define PBCARD_INPUTS_SEQ_TAIL                        0x46u    /* u16 */
#define PBCARD_INPUTS_SEQ_TAIL_ADDR                   0x0BEu   /* absolute */

/* IDENT (writer card, since v2): Identification. Written once when the image is created, with the header. */
#define PBCARD_IDENT_START                            0x0C0u   /* block start */
#define PBCARD_IDENT_SIZE                             16u      /* block length */
#define PBCARD_IDENT_EVENT_BIT                        4u       /* its bit in the pending-events bitmap */
#define PBCARD_IDENT_CARD_TYPE                        0x00u    /* u16 */
#define PBCARD_IDENT_CARD_TYPE_ADDR                   0x0C0u   /* absolute */
#define PBCARD_IDENT_FW_MAJOR                         0x02u    /* u8 */
#define PBCARD_IDENT_FW_MAJOR_ADDR                    0x0C2u   /* absolute */
#define PBCARD_IDENT_FW_MINOR                         0x03u    /* u8 */
#define PBCARD_IDENT_FW_MINOR_ADDR                    0x0C3u   /* absolute */
#define PBCARD_IDENT_FW_PATCH                         0x04u    /* u8 */
#define PBCARD_IDENT_FW_PATCH_ADDR                    0x0C4u   /* absolute */
#define PBCARD_IDENT_IDENT_NUMBER                     0x06u    /* u16 */
#define PBCARD_IDENT_IDENT_NUMBER_ADDR                0x0C6u   /* absolute */
#define PBCARD_IDENT_SERIAL                           0x08u    /* u32 */
#define PBCARD_IDENT_SERIAL_ADDR                      0x0C8u   /* absolute */
#define PBCARD_IDENT_SERIAL_SIZE                      4u       /* bytes */

/* CARD (writer card, sequenced, since v2): Card heartbeat, configuration acknowledge, card → drive event counters. Written on every card cycle. */
#define PBCARD_CARD_START                             0x0D0u   /* block start */
#define PBCARD_CARD_SIZE                              32u      /* block length */
#define PBCARD_CARD_EVENT_BIT                         5u       /* its bit in the pending-events bitmap */
#define PBCARD_CARD_SEQ_HEAD                          0x00u    /* u16 */
#define PBCARD_CARD_SEQ_HEAD_ADDR                     0x0D0u   /* absolute */
#define PBCARD_CARD_HEARTBEAT                         0x02u    /* u16 */
#define PBCARD_CARD_HEARTBEAT_ADDR                    0x0D2u   /* absolute */
#define PBCARD_CARD_FLAGS                             0x04u    /* u8 */
#define PBCARD_CARD_FLAGS_ADDR                        0x0D4u   /* absolute */
#define PBCARD_CARD_CONFIG_RESULT                     0x05u    /* u8 */
#define PBCARD_CARD_CONFIG_RESULT_ADDR                0x0D5u   /* absolute */
#define PBCARD_CARD_CONFIG_ACK                        0x06u    /* u16 */
#define PBCARD_CARD_CONFIG_ACK_ADDR                   0x0D6u   /* absolute */
#define PBCARD_CARD_EVENTS                            0x08u    /* u8[8] */
#define PBCARD_CARD_EVENTS_ADDR                       0x0D8u   /* absolute */
#define PBCARD_CARD_EVENTS_SIZE                       8u       /* bytes */
#define PBCARD_CARD_DRIVE_LOSSES                      0x10u    /* u16 */
#define PBCARD_CARD_DRIVE_LOSSES_ADDR                 0x0E0u   /* absolute */
#define PBCARD_CARD_LATE_RESPONSES                    0x12u    /* u16 */
#define PBCARD_CARD_LATE_RESPONSES_ADDR               0x0E2u   /* absolute */
#define PBCARD_CARD_MAILBOX_TIMEOUTS                  0x14u    /* u16 */
#define PBCARD_CARD_MAILBOX_TIMEOUTS_ADDR             0x0E4u   /* absolute */
#define PBCARD_CARD_BOOT_ID                           0x16u    /* u16 */
#define PBCARD_CARD_BOOT_ID_ADDR                      0x0E6u   /* absolute */
#define PBCARD_CARD_SEQ_TAIL                          0x1Eu    /* u16 */
#define PBCARD_CARD_SEQ_TAIL_ADDR                     0x0EEu   /* absolute */

/* DRIVE (writer host, sequenced, since v2): Drive heartbeat, fault / warning reports, extended diagnosis. Written on every drive cycle. */
#define PBCARD_DRIVE_START                            0x0F0u   /* block start */
#define PBCARD_DRIVE_SIZE                             48u      /* block length */
#define PBCARD_DRIVE_EVENT_BIT                        6u       /* its bit in the pending-events bitmap */
#define PBCARD_DRIVE_SEQ_HEAD                         0x00u    /* u16 */
#define PBCARD_DRIVE_SEQ_HEAD_ADDR                    0x0F0u   /* absolute */
#define PBCARD_DRIVE_HEARTBEAT                        0x02u    /* u16 */
#define PBCARD_DRIVE_HEARTBEAT_ADDR                   0x0F2u   /* absolute */
#define PBCARD_DRIVE_FAULT_CODE                       0x04u    /* u16 */
#define PBCARD_DRIVE_FAULT_CODE_ADDR                  0x0F4u   /* absolute */
#define PBCARD_DRIVE_WARNING_CODE                     0x06u    /* u16 */
#define PBCARD_DRIVE_WARNING_CODE_ADDR                0x0F6u   /* absolute */
#define PBCARD_DRIVE_FAULT_COUNT                      0x08u    /* u8 */
#define PBCARD_DRIVE_FAULT_COUNT_ADDR                 0x0F8u   /* absolute */
#define PBCARD_DRIVE_WARNING_COUNT                    0x09u    /* u8 */
#define PBCARD_DRIVE_WARNING_COUNT_ADDR               0x0F9u   /* absolute */
#define PBCARD_DRIVE_EXT_DIAG_LEN                     0x0Au    /* u8 */
#define PBCARD_DRIVE_EXT_DIAG_LEN_ADDR                0x0FAu   /* absolute */
#define PBCARD_DRIVE_EXT_DIAG                         0x0Cu    /* u8[32] */
#define PBCARD_DRIVE_EXT_DIAG_ADDR                    0x0FCu   /* absolute */
#define PBCARD_DRIVE_EXT_DIAG_SIZE                    32u      /* bytes */
#define PBCARD_DRIVE_IRQ_MASK                         0x2Cu    /* u16 */
#define PBCARD_DRIVE_IRQ_MASK_ADDR                    0x11Cu   /* absolute */
#define PBCARD_DRIVE_SEQ_TAIL                         0x2Eu    /* u16 */
#define PBCARD_DRIVE_SEQ_TAIL_ADDR                    0x11Eu   /* absolute */

/* CONFIG (writer host, sequenced, since v2): Configuration from the drive. Taken over only while no cyclic exchange runs; acknowledged in CARD. */
#define PBCARD_CONFIG_START                           0x120u   /* block start */
#define PBCARD_CONFIG_SIZE                            48u      /* block length */
#define PBCARD_CONFIG_EVENT_BIT                       7u       /* its bit in the pending-events bitmap */
#define PBCARD_CONFIG_SEQ_HEAD                        0x00u    /* u16 */
#define PBCARD_CONFIG_SEQ_HEAD_ADDR                   0x120u   /* absolute */
#define PBCARD_CONFIG_STATION_ADDRESS                 0x02u    /* u8 */
#define PBCARD_CONFIG_STATION_ADDRESS_ADDR            0x122u   /* absolute */
#define PBCARD_CONFIG_PROFILE                         0x03u    /* u8 */
#define PBCARD_CONFIG_PROFILE_ADDR                    0x123u   /* absolute */
#define PBCARD_CONFIG_OPERATE_MODE                    0x04u    /* u8 */
#define PBCARD_CONFIG_OPERATE_MODE_ADDR               0x124u   /* absolute */
#define PBCARD_CONFIG_COMM_LOSS_REACTION              0x05u    /* u8 */
#define PBCARD_CONFIG_COMM_LOSS_REACTION_ADDR         0x125u   /* absolute */
#define PBCARD_CONFIG_TELEGRAM                        0x06u    /* u16 */
#define PBCARD_CONFIG_TELEGRAM_ADDR                   0x126u   /* absolute */
#define PBCARD_CONFIG_COMM_LOSS_DELAY_MS              0x08u    /* u16 */
#define PBCARD_CONFIG_COMM_LOSS_DELAY_MS_ADDR         0x128u   /* absolute */
#define PBCARD_CONFIG_PZD_OUT_MAP                     0x0Au    /* u16[8] */
#define PBCARD_CONFIG_PZD_OUT_MAP_ADDR                0x12Au   /* absolute */
#define PBCARD_CONFIG_PZD_OUT_MAP_SIZE                16u      /* bytes */
#define PBCARD_CONFIG_PZD_IN_MAP                      0x1Au    /* u16[8] */
#define PBCARD_CONFIG_PZD_IN_MAP_ADDR                 0x13Au   /* absolute */
#define PBCARD_CONFIG_PZD_IN_MAP_SIZE                 16u      /* bytes */
#define PBCARD_CONFIG_IO_UPDATE_DELAY                 0x2Au    /* u16 */
#define PBCARD_CONFIG_IO_UPDATE_DELAY_ADDR            0x14Au   /* absolute */
#define PBCARD_CONFIG_SEQ_TAIL                        0x2Eu    /* u16 */
#define PBCARD_CONFIG_SEQ_TAIL_ADDR                   0x14Eu   /* absolute */

/* MBX_REQ (writer card, sequenced, since v2): Parameter mailbox request. A new REQ_ID is a new request. */
#define PBCARD_MBX_REQ_START                          0x150u   /* block start */
#define PBCARD_MBX_REQ_SIZE                           144u     /* block length */
#define PBCARD_MBX_REQ_EVENT_BIT                      8u       /* its bit in the pending-events bitmap */
#define PBCARD_MBX_REQ_SEQ_HEAD                       0x00u    /* u16 */
#define PBCARD_MBX_REQ_SEQ_HEAD_ADDR                  0x150u   /* absolute */
#define PBCARD_MBX_REQ_REQ_ID                         0x02u    /* u16 */
#define PBCARD_MBX_REQ_REQ_ID_ADDR                    0x152u   /* absolute */
#define PBCARD_MBX_REQ_KIND                           0x04u    /* u8 */
#define PBCARD_MBX_REQ_KIND_ADDR                      0x154u   /* absolute */
#define PBCARD_MBX_REQ_AXIS                           0x05u    /* u8 */
#define PBCARD_MBX_REQ_AXIS_ADDR                      0x155u   /* absolute */
#define PBCARD_MBX_REQ_PNU                            0x06u    /* u16 */
#define PBCARD_MBX_REQ_PNU_ADDR                       0x156u   /* absolute */
#define PBCARD_MBX_REQ_SUBINDEX                       0x08u    /* u16 */
#define PBCARD_MBX_REQ_SUBINDEX_ADDR                  0x158u   /* absolute */
#define PBCARD_MBX_REQ_COUNT                          0x0Au    /* u8 */
#define PBCARD_MBX_REQ_COUNT_ADDR                     0x15Au   /* absolute */
#define PBCARD_MBX_REQ_FORMAT                         0x0Bu    /* u8 */
#define PBCARD_MBX_REQ_FORMAT_ADDR                    0x15Bu   /* absolute */
#define PBCARD_MBX_REQ_VALUES_LEN                     0x0Cu    /* u8 */
#define PBCARD_MBX_REQ_VALUES_LEN_ADDR                0x15Cu   /* absolute */
#define PBCARD_MBX_REQ_VALUES                         0x0Eu    /* u8[128] */
#define PBCARD_MBX_REQ_VALUES_ADDR                    0x15Eu   /* absolute */
#define PBCARD_MBX_REQ_VALUES_SIZE                    128u     /* bytes */
#define PBCARD_MBX_REQ_SEQ_TAIL                       0x8Eu    /* u16 */
#define PBCARD_MBX_REQ_SEQ_TAIL_ADDR                  0x1DEu   /* absolute */

/* MBX_RSP (writer host, sequenced, since v2): Parameter mailbox response. Taken only when REQ_ID names the outstanding request. */
#define PBCARD_MBX_RSP_START                          0x1E0u   /* block start */
#define PBCARD_MBX_RSP_SIZE                           144u     /* block length */
#define PBCARD_MBX_RSP_EVENT_BIT                      9u       /* its bit in the pending-events bitmap */
#define PBCARD_MBX_RSP_SEQ_HEAD                       0x00u    /* u16 */
#define PBCARD_MBX_RSP_SEQ_HEAD_ADDR                  0x1E0u   /* absolute */
#define PBCARD_MBX_RSP_REQ_ID                         0x02u    /* u16 */
#define PBCARD_MBX_RSP_REQ_ID_ADDR                    0x1E2u   /* absolute */
#define PBCARD_MBX_RSP_RESULT                         0x04u    /* u8 */
#define PBCARD_MBX_RSP_RESULT_ADDR                    0x1E4u   /* absolute */
#define PBCARD_MBX_RSP_FORMAT                         0x05u    /* u8 */
#define PBCARD_MBX_RSP_FORMAT_ADDR                    0x1E5u   /* absolute */
#define PBCARD_MBX_RSP_COUNT                          0x06u    /* u8 */
#define PBCARD_MBX_RSP_COUNT_ADDR                     0x1E6u   /* absolute */
#define PBCARD_MBX_RSP_VALUES_LEN                     0x07u    /* u8 */
#define PBCARD_MBX_RSP_VALUES_LEN_ADDR                0x1E7u   /* absolute */
#define PBCARD_MBX_RSP_ERROR                          0x08u    /* u16 */
#define PBCARD_MBX_RSP_ERROR_ADDR                     0x1E8u   /* absolute */
#define PBCARD_MBX_RSP_ERROR_INFO                     0x0Au    /* u16 */
#define PBCARD_MBX_RSP_ERROR_INFO_ADDR                0x1EAu   /* absolute */
#define PBCARD_MBX_RSP_HAS_INFO                       0x0Cu    /* u8 */
#define PBCARD_MBX_RSP_HAS_INFO_ADDR                  0x1ECu   /* absolute */
#define PBCARD_MBX_RSP_VALUES                         0x0Eu    /* u8[128] */
#define PBCARD_MBX_RSP_VALUES_ADDR                    0x1EEu   /* absolute */
#define PBCARD_MBX_RSP_VALUES_SIZE                    128u     /* bytes */
#define PBCARD_MBX_RSP_SEQ_TAIL                       0x8Eu    /* u16 */
#define PBCARD_MBX_RSP_SEQ_TAIL_ADDR                  0x26Eu   /* absolute */

/* DRIVE_CMD (writer card, sequenced, since v3): Drive-neutral command (run / stop kinds, setpoint, fault resets, …), operate mode, telegram, extra PZD output words. Written after OUTPUTS in the same card cycle. */
#define PBCARD_DRIVE_CMD_START                        0x270u   /* block start */
#define PBCARD_DRIVE_CMD_SIZE                         48u      /* block length */
#define PBCARD_DRIVE_CMD_EVENT_BIT                    10u      /* its bit in the pending-events bitmap */
#define PBCARD_DRIVE_CMD_SEQ_HEAD                     0x00u    /* u16 */
#define PBCARD_DRIVE_CMD_SEQ_HEAD_ADDR                0x270u   /* absolute */
#define PBCARD_DRIVE_CMD_FLAGS                        0x02u    /* u16 */
#define PBCARD_DRIVE_CMD_FLAGS_ADDR                   0x272u   /* absolute */
#define PBCARD_DRIVE_CMD_SPEED_SETPOINT               0x04u    /* i16 */
#define PBCARD_DRIVE_CMD_SPEED_SETPOINT_ADDR          0x274u   /* absolute */
#define PBCARD_DRIVE_CMD_FAULT_RESETS                 0x06u    /* u8 */
#define PBCARD_DRIVE_CMD_FAULT_RESETS_ADDR            0x276u   /* absolute */
#define PBCARD_DRIVE_CMD_COMM_LOSS_REACTION           0x07u    /* u8 */
#define PBCARD_DRIVE_CMD_COMM_LOSS_REACTION_ADDR      0x277u   /* absolute */
#define PBCARD_DRIVE_CMD_OPERATE_MODE                 0x08u    /* u8 */
#define PBCARD_DRIVE_CMD_OPERATE_MODE_ADDR            0x278u   /* absolute */
#define PBCARD_DRIVE_CMD_EXTRA_COUNT                  0x09u    /* u8 */
#define PBCARD_DRIVE_CMD_EXTRA_COUNT_ADDR             0x279u   /* absolute */
#define PBCARD_DRIVE_CMD_TELEGRAM                     0x0Au    /* u16 */
#define PBCARD_DRIVE_CMD_TELEGRAM_ADDR                0x27Au   /* absolute */
#define PBCARD_DRIVE_CMD_OUTPUTS_SEQ                  0x0Cu    /* u16 */
#define PBCARD_DRIVE_CMD_OUTPUTS_SEQ_ADDR             0x27Cu   /* absolute */
#define PBCARD_DRIVE_CMD_EXTRA                        0x0Eu    /* u16[16] */
#define PBCARD_DRIVE_CMD_EXTRA_ADDR                   0x27Eu   /* absolute */
#define PBCARD_DRIVE_CMD_EXTRA_SIZE                   32u      /* bytes */
#define PBCARD_DRIVE_CMD_SEQ_TAIL                     0x2Eu    /* u16 */
#define PBCARD_DRIVE_CMD_SEQ_TAIL_ADDR                0x29Eu   /* absolute */

/* DRIVE_STATE (writer host, sequenced, since v3): Drive-neutral status (state bits, speed, current, torque, power, fault, warning, NAMUR), extra PZD input words. Written after INPUTS every drive cycle. */
#define PBCARD_DRIVE_STATE_START                      0x2A0u   /* block start */
#define PBCARD_DRIVE_STATE_SIZE                       56u      /* block length */
#define PBCARD_DRIVE_STATE_EVENT_BIT                  11u      /* its bit in the pending-events bitmap */
#define PBCARD_DRIVE_STATE_SEQ_HEAD                   0x00u    /* u16 */
#define PBCARD_DRIVE_STATE_SEQ_HEAD_ADDR              0x2A0u   /* absolute */
#define PBCARD_DRIVE_STATE_FLAGS                      0x02u    /* u16 */
#define PBCARD_DRIVE_STATE_FLAGS_ADDR                 0x2A2u   /* absolute */
#define PBCARD_DRIVE_STATE_SPEED                      0x04u    /* i16 */
#define PBCARD_DRIVE_STATE_SPEED_ADDR                 0x2A4u   /* absolute */
#define PBCARD_DRIVE_STATE_CURRENT                    0x06u    /* i16 */
#define PBCARD_DRIVE_STATE_CURRENT_ADDR               0x2A6u   /* absolute */
#define PBCARD_DRIVE_STATE_TORQUE                     0x08u    /* i16 */
#define PBCARD_DRIVE_STATE_TORQUE_ADDR                0x2A8u   /* absolute */
#define PBCARD_DRIVE_STATE_POWER                      0x0Au    /* i16 */
#define PBCARD_DRIVE_STATE_POWER_ADDR                 0x2AAu   /* absolute */
#define PBCARD_DRIVE_STATE_FAULT_CODE                 0x0Cu    /* u16 */
#define PBCARD_DRIVE_STATE_FAULT_CODE_ADDR            0x2ACu   /* absolute */
#define PBCARD_DRIVE_STATE_WARNING_CODE               0x0Eu    /* u16 */
#define PBCARD_DRIVE_STATE_WARNING_CODE_ADDR          0x2AEu   /* absolute */
#define PBCARD_DRIVE_STATE_NAMUR                      0x10u    /* u16 */
#define PBCARD_DRIVE_STATE_NAMUR_ADDR                 0x2B0u   /* absolute */
#define PBCARD_DRIVE_STATE_INPUTS_SEQ                 0x12u    /* u16 */
#define PBCARD_DRIVE_STATE_INPUTS_SEQ_ADDR            0x2B2u   /* absolute */
#define PBCARD_DRIVE_STATE_EXTRA_COUNT                0x14u    /* u8 */
#define PBCARD_DRIVE_STATE_EXTRA_COUNT_ADDR           0x2B4u   /* absolute */
#define PBCARD_DRIVE_STATE_EXTRA                      0x16u    /* u16[16] */
#define PBCARD_DRIVE_STATE_EXTRA_ADDR                 0x2B6u   /* absolute */
#define PBCARD_DRIVE_STATE_EXTRA_SIZE                 32u      /* bytes */
#define PBCARD_DRIVE_STATE_SEQ_TAIL                   0x36u    /* u16 */
#define PBCARD_DRIVE_STATE_SEQ_TAIL_ADDR              0x2D6u   /* absolute */

/* DEVICE (writer host, sequenced, since v4): The drive's serial number and hardware revision, which the card reports in I&M0 (DP-V1 slot 0 index 255). Written once after the drive starts. */
#define PBCARD_DEVICE_START                           0x2D8u   /* block start */
#define PBCARD_DEVICE_SIZE                            24u      /* block length */
#define PBCARD_DEVICE_EVENT_BIT                       12u      /* its bit in the pending-events bitmap */
#define PBCARD_DEVICE_SEQ_HEAD                        0x00u    /* u16 */
#define PBCARD_DEVICE_SEQ_HEAD_ADDR                   0x2D8u   /* absolute */
#define PBCARD_DEVICE_SERIAL_NUMBER                   0x02u    /* u8[16] */
#define PBCARD_DEVICE_SERIAL_NUMBER_ADDR              0x2DAu   /* absolute */
#define PBCARD_DEVICE_SERIAL_NUMBER_SIZE              16u      /* bytes */
#define PBCARD_DEVICE_HARDWARE_REVISION               0x12u    /* u16 */
#define PBCARD_DEVICE_HARDWARE_REVISION_ADDR          0x2EAu   /* absolute */
#define PBCARD_DEVICE_SEQ_TAIL                        0x16u    /* u16 */
#define PBCARD_DEVICE_SEQ_TAIL_ADDR                   0x2EEu   /* absolute */

/* ---- the SPI frames (docs/SPI.md) ---- */
#define PBCARD_SPI_PROTOCOL_VERSION                   2u       /* STATUS data byte 0 */
#define PBCARD_SPI_CMD_READ                           0xA1u    /* request CMD */
#define PBCARD_SPI_CMD_WRITE                          0xB2u    /* request CMD */
#define PBCARD_SPI_CMD_STATUS                         0xC4u    /* request CMD */
#define PBCARD_SPI_CMD_CYCLIC                         0xD8u    /* request CMD */
#define PBCARD_SPI_RESULT_OK                          0x80u    /* reply RESULT */
#define PBCARD_SPI_RESULT_CRC_ERROR                   0x81u    /* reply RESULT (line error: repeat) */
#define PBCARD_SPI_RESULT_BAD_COMMAND                 0x82u    /* reply RESULT (line error: repeat) */
#define PBCARD_SPI_RESULT_BAD_LENGTH                  0x83u    /* reply RESULT (line error: repeat) */
#define PBCARD_SPI_RESULT_BAD_ADDRESS                 0x84u    /* reply RESULT */
#define PBCARD_SPI_RESULT_FORBIDDEN_WRITE             0x85u    /* reply RESULT */
#define PBCARD_SPI_NO_REPLY                           0u       /* reply byte 0: no reply in this transaction */
#define PBCARD_SPI_FLAG_EVENTS                        1u       /* reply FLAGS: events pending (IRQ) */
#define PBCARD_SPI_REQUEST_HEADER                     6u       /* CMD TAG ADDR LEN */
#define PBCARD_SPI_REPLY_HEADER                       8u       /* RESULT TAG CMD FLAGS ADDR LEN */
#define PBCARD_SPI_CRC_LEN                            2u       /* CRC-16/CCITT-FALSE, high byte first */
#define PBCARD_SPI_MAX_DATA                           1024u    /* most DATA bytes of a READ / WRITE */
#define PBCARD_SPI_MAX_REQUEST                        1032u    /* longest request frame */
#define PBCARD_SPI_MAX_REPLY                          1034u    /* longest reply frame */
#define PBCARD_SPI_MAX_TRANSACTION                    1034u    /* longest transaction */
#define PBCARD_SPI_STATUS_LEN                         20u      /* bytes of STATUS data */
#define PBCARD_SPI_WRITE_ECHO_LEN                     2u       /* WRITE reply DATA: the request's CRC */
#define PBCARD_SPI_T_READY_US                         200u     /* gap between two transactions */
#define PBCARD_SPI_STATUS_VERSION                     0u       /* STATUS data: protocol version */
#define PBCARD_SPI_STATUS_MAX_DATA                    2u       /* STATUS data: u16 MAX_DATA */
#define PBCARD_SPI_STATUS_IMAGE_SIZE                  4u       /* STATUS data: u16 image size */
#define PBCARD_SPI_STATUS_EVENTS                      6u       /* STATUS data: u16 pending events */
#define PBCARD_SPI_STATUS_COUNTERS                    8u       /* STATUS data: u16 x 6 counters */
#define PBCARD_SPI_CRC_POLY                           0x1021u  /* CRC-16/CCITT-FALSE polynomial */
#define PBCARD_SPI_CRC_INIT                           0xFFFFu  /* initial value, no reflection, no final XOR */
#define PBCARD_SPI_CRC_CHECK                          0x29B1u  /* crc of "123456789" */

/* CYCLIC request DATA (docs/SPI.md, "The CYCLIC exchange") */
#define PBCARD_CYC_REQ_HEARTBEAT                      0u       /* offset in the request DATA */
#define PBCARD_CYC_REQ_DRIVE_SEQ                      2u       /* offset in the request DATA */
#define PBCARD_CYC_REQ_STATE_SEQ                      4u       /* offset in the request DATA */
#define PBCARD_CYC_REQ_STATE_LEN                      6u       /* offset in the request DATA */
#define PBCARD_CYC_REQ_RSP_OFF                        7u       /* offset in the request DATA */
#define PBCARD_CYC_REQ_RSP_LEN                        8u       /* offset in the request DATA */
#define PBCARD_CYC_REQ_REQ_OFF                        9u       /* offset in the request DATA */
#define PBCARD_CYC_REQ_REQ_LEN                        10u      /* offset in the request DATA */
#define PBCARD_CYC_REQ_STATE                          11u      /* offset in the request DATA */
/* CYCLIC reply DATA */
#define PBCARD_CYC_REP_EVENTS                         0u       /* offset in the reply DATA */
#define PBCARD_CYC_REP_CARD_HEARTBEAT                 2u       /* offset in the reply DATA */
#define PBCARD_CYC_REP_CARD_FLAGS                     4u       /* offset in the reply DATA */
#define PBCARD_CYC_REP_COMM_STATE                     5u       /* offset in the reply DATA */
#define PBCARD_CYC_REP_BOOT_ID                        6u       /* offset in the reply DATA */
#define PBCARD_CYC_REP_CARD_EVENTS                    8u       /* offset in the reply DATA */
#define PBCARD_CYC_REP_CMD_SEQ                        16u      /* offset in the reply DATA */
#define PBCARD_CYC_REP_CMD_LEN                        18u      /* offset in the reply DATA */
#define PBCARD_CYC_REP_REQ_LEN                        19u      /* offset in the reply DATA */
#define PBCARD_CYC_REP_CMD                            20u      /* offset in the reply DATA */
#define PBCARD_CYC_REQUEST_FIXED                      11u      /* request DATA before STATE */
#define PBCARD_CYC_REPLY_FIXED                        20u      /* reply DATA before CMD */
#define PBCARD_CYC_STATE_PAYLOAD                      52u      /* DRIVE_STATE bytes from FLAGS to the tail */
#define PBCARD_CYC_STATE_BASE                         16u      /* DRIVE_STATE bytes FLAGS..NAMUR */
#define PBCARD_CYC_CMD_BASE                           12u      /* DRIVE_CMD bytes FLAGS..EXTRA */
#define PBCARD_CYC_MAX_FRAGMENT                       32u      /* most bytes of a mailbox fragment */
#define PBCARD_CYC_MIN_FRAGMENT                       4u       /* fewest bytes of a mailbox fragment the reference hosts use */
#define PBCARD_CYC_TRANSACTION_BYTES                  64u      /* the reference hosts' CYCLIC transaction budget (the mailbox fragments get what the telegram leaves) */
#define PBCARD_CYC_MAX_REQUEST_DATA                   95u      /* longest CYCLIC request DATA */
#define PBCARD_CYC_MAX_REPLY_DATA                     96u      /* longest CYCLIC reply DATA */

#endif /* PBCARD_DPM_H */
