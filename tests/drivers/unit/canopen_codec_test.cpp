// CiA 301 / CiA 402 encoding checked byte by byte against the standard's tables.
#include <gtest/gtest.h>
#include <linux/can/error.h>

#include "hil/drv/canopen.hpp"

namespace hil::drv {
namespace {

using namespace canopen;

std::vector<int> bytes(const CanFrame& f) { return std::vector<int>(f.data.begin(), f.data.begin() + f.dlc); }

TEST(CanopenCodec, NmtIsCobId0WithCommandThenNode) {
  const auto f = nmt(NmtCommand::reset_communication, 5);
  EXPECT_EQ(f.id, 0x000u);
  EXPECT_EQ(bytes(f), (std::vector<int>{0x82, 0x05}));
  EXPECT_EQ(bytes(nmt(NmtCommand::start, 0)), (std::vector<int>{0x01, 0x00}));
  EXPECT_EQ(bytes(nmt(NmtCommand::stop, 3)), (std::vector<int>{0x02, 0x03}));
  EXPECT_EQ(bytes(nmt(NmtCommand::enter_pre_operational, 3)), (std::vector<int>{0x80, 0x03}));
  EXPECT_EQ(bytes(nmt(NmtCommand::reset_node, 3)), (std::vector<int>{0x81, 0x03}));
}

TEST(CanopenCodec, SyncAndHeartbeat) {
  EXPECT_EQ(sync().id, 0x080u);
  EXPECT_EQ(sync().dlc, 0);
  const auto hb = heartbeat(7, NmtState::operational);
  EXPECT_EQ(hb.id, 0x707u);
  EXPECT_EQ(bytes(hb), (std::vector<int>{0x05}));
}

// CiA 301 7.3.5's table of restricted CAN-IDs, at each range's edges.
TEST(CanopenCodec, RestrictedCanIdsAreTheStandardsRanges) {
  for (std::uint32_t id :
       {0x000u, 0x001u, 0x07Fu, 0x101u, 0x180u, 0x581u, 0x5FFu, 0x601u, 0x67Fu, 0x6E0u, 0x6FFu, 0x701u, 0x77Fu, 0x780u, 0x7FFu})
    EXPECT_TRUE(canopen::restricted_can_id(id)) << std::hex << id;
  for (std::uint32_t id : {0x080u, 0x100u, 0x181u, 0x185u, 0x205u, 0x4FFu, 0x580u, 0x600u, 0x680u, 0x6DFu, 0x700u})
    EXPECT_FALSE(canopen::restricted_can_id(id)) << std::hex << id;
}

TEST(CanopenCodec, SdoDownloadCommandSpecifierBySize) {
  // 1, 2, 3, 4 data bytes: 0x2F, 0x2B, 0x27, 0x23; index little-endian, then sub-index.
  EXPECT_EQ(bytes(sdo_download(5, 0x6060, 0, 8, 1)), (std::vector<int>{0x2F, 0x60, 0x60, 0x00, 0x08, 0, 0, 0}));
  EXPECT_EQ(bytes(sdo_download(5, 0x1017, 0, 100, 2)), (std::vector<int>{0x2B, 0x17, 0x10, 0x00, 100, 0, 0, 0}));
  EXPECT_EQ(sdo_download(5, 0x2000, 1, 0x123456, 3).data[0], 0x27);
  EXPECT_EQ(bytes(sdo_download(5, 0x1600, 1, 0x60400010, 4)), (std::vector<int>{0x23, 0x00, 0x16, 0x01, 0x10, 0x00, 0x40, 0x60}));
  EXPECT_EQ(sdo_download(5, 0x1600, 1, 0, 4).id, 0x605u);
  EXPECT_EQ(bytes(sdo_upload(5, 0x6064, 0)), (std::vector<int>{0x40, 0x64, 0x60, 0x00, 0, 0, 0, 0}));
}

TEST(CanopenCodec, SdoRepliesParse) {
  const auto up = parse_sdo_reply(sdo_upload_ok(5, 0x6061, 0, 8, 1));
  EXPECT_EQ(sdo_upload_ok(5, 0x6061, 0, 8, 1).id, 0x585u);
  EXPECT_EQ(sdo_upload_ok(5, 0x6061, 0, 8, 1).data[0], 0x4F);
  EXPECT_EQ(sdo_upload_ok(5, 0x6041, 0, 8, 2).data[0], 0x4B);
  EXPECT_EQ(sdo_upload_ok(5, 0x6064, 0, 8, 4).data[0], 0x43);
  EXPECT_EQ(up.kind, SdoReply::Kind::upload);
  EXPECT_EQ(up.index, 0x6061);
  EXPECT_EQ(up.size, 1);
  EXPECT_EQ(up.value, 8u);
  EXPECT_EQ(sdo_download_ok(5, 0x6060, 0).data[0], 0x60);
  EXPECT_EQ(parse_sdo_reply(sdo_download_ok(5, 0x6060, 0)).kind, SdoReply::Kind::download);
  const auto ab = sdo_abort(5, 0x2000, 0, 0x06020000, true);
  EXPECT_EQ(bytes(ab), (std::vector<int>{0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x02, 0x06}));
  const auto r = parse_sdo_reply(ab);
  EXPECT_EQ(r.kind, SdoReply::Kind::abort);
  EXPECT_EQ(r.value, 0x06020000u);
  // An upload response without the expedited bit starts a segmented transfer.
  CanFrame seg = sdo_upload_ok(5, 0x1008, 0, 20, 4);
  seg.data[0] = 0x41;
  EXPECT_EQ(parse_sdo_reply(seg).kind, SdoReply::Kind::unsupported);
  CanFrame shorty = sdo_download_ok(5, 0x6060, 0);
  shorty.dlc = 4;
  EXPECT_EQ(parse_sdo_reply(shorty).kind, SdoReply::Kind::malformed);
}

TEST(CanopenCodec, AbortCodesByName) {
  EXPECT_EQ(sdo_abort_name(0x06020000), "object does not exist in the object dictionary");
  EXPECT_EQ(sdo_abort_name(0x06090011), "sub-index does not exist");
  EXPECT_EQ(sdo_abort_name(0x06010002), "attempt to write a read only object");
  EXPECT_EQ(sdo_abort_name(0x05040000), "SDO protocol timed out");
  EXPECT_EQ(sdo_abort_name(0x12345678), "unknown abort code");
  EXPECT_EQ(object_name(0x607A, 0), "0x607A:00");
}

TEST(CanopenCodec, EmcyDecoding) {
  CanFrame f;
  f.id = 0x085;
  f.dlc = 8;
  f.data = {0x10, 0x23, 0x03, 0x01, 0x02, 0x03, 0x04, 0x05};
  const auto e = parse_emcy(f);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->error_code, 0x2310);
  EXPECT_EQ(e->error_register, 0x03);
  EXPECT_EQ(e->manufacturer, (std::array<std::uint8_t, 5>{1, 2, 3, 4, 5}));
  EXPECT_EQ(
      describe(*e),
      "EMCY 0x2310 (continuous over current, device output side), register 0x03 (generic, current), manufacturer 01 02 03 04 05");
  EXPECT_EQ(emcy_class_name(0x8130),
            "life guard or heartbeat error: the drive lost a heartbeat it consumes (0x1016) or life guarding");
  EXPECT_EQ(emcy_class_name(0x0000), "error reset or no error");
  EXPECT_EQ(emcy_class_name(0x4210), "excess temperature, device");  // CiA 402's own code
  EXPECT_EQ(emcy_class_name(0x4280), "device temperature");          // else the class
  EXPECT_EQ(emcy_class_name(0x7121), "motor blocked");
  EXPECT_EQ(emcy(5, *e).data, f.data);
  f.dlc = 5;
  EXPECT_FALSE(parse_emcy(f));
}

TEST(Cia402, StatuswordStatesPerTable) {
  using cia402::State;
  EXPECT_EQ(cia402::decode_statusword(0x0000), State::not_ready_to_switch_on);
  EXPECT_EQ(cia402::decode_statusword(0x0250), State::switch_on_disabled);
  EXPECT_EQ(cia402::decode_statusword(0x0231), State::ready_to_switch_on);
  EXPECT_EQ(cia402::decode_statusword(0x0233), State::switched_on);
  EXPECT_EQ(cia402::decode_statusword(0x1237), State::operation_enabled);
  EXPECT_EQ(cia402::decode_statusword(0x0217), State::quick_stop_active);
  EXPECT_EQ(cia402::decode_statusword(0x021F), State::fault_reaction_active);
  EXPECT_EQ(cia402::decode_statusword(0x0218), State::fault);
}

TEST(Cia402, ControlwordSequenceToOperationEnabled) {
  using cia402::State;
  using cia402::Target;
  const auto op = Target::operation_enabled;
  EXPECT_EQ(cia402::next_controlword(State::switch_on_disabled, op, false), 0x0006);                  // shutdown
  EXPECT_EQ(cia402::next_controlword(State::ready_to_switch_on, op, false), 0x0007);                  // switch on
  EXPECT_EQ(cia402::next_controlword(State::switched_on, op, false), 0x000F);                         // enable operation
  EXPECT_EQ(cia402::next_controlword(State::operation_enabled, Target::switched_on, false), 0x0007);  // disable op
  EXPECT_EQ(cia402::next_controlword(State::fault, op, true), 0x0080);                                // fault reset
  EXPECT_EQ(cia402::next_controlword(State::fault, op, false), 0x0000);  // bit 7 low for the next edge
  EXPECT_EQ(cia402::next_controlword(State::quick_stop_active, op, false), 0x0000);
  // Quick stop (CiA 402 transition 11): 0x0002 from operation enabled, held while the drive
  // ramps down (quick stop active); once it is switch on disabled the client stays there.
  const auto qs = Target::quick_stop;
  EXPECT_EQ(cia402::next_controlword(State::operation_enabled, qs, false), 0x0002);
  EXPECT_EQ(cia402::next_controlword(State::quick_stop_active, qs, false), 0x0002);
  EXPECT_EQ(cia402::next_controlword(State::switch_on_disabled, qs, false), 0x0000);
  EXPECT_EQ(cia402::next_controlword(State::ready_to_switch_on, qs, false), 0x0000);
  EXPECT_EQ(cia402::next_controlword(State::switched_on, qs, false), 0x0000);
}

TEST(CanErrors, DecodedFromLinuxErrorFrames) {
  CanFrame f;
  f.error = true;
  f.dlc = 8;
  f.id = CAN_ERR_BUSOFF;
  auto e = decode_error_frame(f);
  EXPECT_TRUE(e.bus_off);
  EXPECT_EQ(e.text, "bus-off");
  f.id = CAN_ERR_CRTL;
  f.data[1] = CAN_ERR_CRTL_RX_PASSIVE;
  e = decode_error_frame(f);
  EXPECT_TRUE(e.error_passive);
  EXPECT_EQ(e.text, "controller problem: rx-error-passive");
  f.data[1] = CAN_ERR_CRTL_TX_WARNING;
  EXPECT_TRUE(decode_error_frame(f).error_warning);
  f.id = CAN_ERR_RESTARTED;
  EXPECT_TRUE(decode_error_frame(f).restarted);
  f.id = CAN_ERR_ACK | CAN_ERR_BUSERROR;
  EXPECT_EQ(decode_error_frame(f).text, "no ack, bus error");

  BusStateTracker t;
  EXPECT_TRUE(t.update(decode_error_frame(make_error_frame(EmulatedBusError::error_warning))));
  EXPECT_EQ(t.state(), BusState::error_warning);
  t.update(decode_error_frame(make_error_frame(EmulatedBusError::error_passive)));
  EXPECT_EQ(t.state(), BusState::error_passive);
  t.update(decode_error_frame(make_error_frame(EmulatedBusError::bus_off)));
  EXPECT_EQ(t.state(), BusState::bus_off);
  t.update(decode_error_frame(make_error_frame(EmulatedBusError::error_passive)));
  EXPECT_EQ(t.state(), BusState::bus_off);  // only a restart leaves bus-off
  t.update(decode_error_frame(make_error_frame(EmulatedBusError::restarted)));
  EXPECT_EQ(t.state(), BusState::error_active);
  EXPECT_EQ(to_string(make_error_frame(EmulatedBusError::bus_off)), "20000040#0000000000000000");
}

}  // namespace
}  // namespace hil::drv
