// haptics/igtl_device.h: the OpenIGTLink device against libOpenIGTLink's own
// client on 127.0.0.1 (port 0: any free one, so tests run side by side).
#include <gtest/gtest.h>

#include <sys/socket.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>

#include <igtlClientSocket.h>
#include <igtlMessageHeader.h>
#include <igtlSensorMessage.h>
#include <igtlStatusMessage.h>
#include <igtlStringMessage.h>
#include <igtlTransformMessage.h>
#include <igtlUnit.h>
#include <igtl_header.h>

#include "engine/util/error.h"
#include "haptics/haptic_loop.h"
#include "haptics/igtl_device.h"

namespace incise {
namespace {

using Clock = std::chrono::steady_clock;
using Force = std::array<double, 3>;

template <class Pred>
bool eventually(Pred pred, double seconds = 2.0) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
  while (!pred()) {
    if (Clock::now() > deadline) return false;
    std::this_thread::yield();
  }
  return true;
}

// 1.11's CloseSocket() only shutdown()s; close the descriptor as well so the
// tests leak none (the library keeps it protected).
struct SocketFd : igtl::Socket {
  static int& of(igtl::Socket& s) { return s.*(&SocketFd::m_SocketDescriptor); }
};

class Client {
 public:
  explicit Client(int port) : socket_(igtl::ClientSocket::New()) {
    connected_ = socket_->ConnectToServer("127.0.0.1", port) == 0;
    if (connected_) socket_->SetReceiveTimeout(2000);  // a missing reply fails the test, never hangs it
  }
  ~Client() { close(); }
  bool connected() const { return connected_; }

  void close() {
    int& fd = SocketFd::of(*socket_);
    if (fd < 0) return;
    ::shutdown(fd, SHUT_RDWR);
    ::close(fd);
    fd = -1;
  }

  bool send(igtl::MessageBase& msg) {
    msg.Pack();
    return socket_->Send(msg.GetPackPointer(), msg.GetPackSize()) == 1;
  }

  bool send_raw(const void* data, int size) { return socket_->Send(data, size) == 1; }

  bool send_transform(const igtl::Matrix4x4& m) {
    igtl::TransformMessage::Pointer msg = igtl::TransformMessage::New();
    msg->SetDeviceName("StylusToTracker");
    igtl::Matrix4x4 copy;
    std::memcpy(copy, m, sizeof copy);
    msg->SetMatrix(copy);
    return send(*msg);
  }

  // The next message, which must be the SENSOR "FORCE" reply.
  ::testing::AssertionResult receive_force(Force& f) {
    igtl::MessageHeader::Pointer header = igtl::MessageHeader::New();
    header->InitPack();
    if (socket_->Receive(header->GetPackPointer(), header->GetPackSize()) != header->GetPackSize())
      return ::testing::AssertionFailure() << "no reply";
    if (!(header->Unpack() & igtl::MessageHeader::UNPACK_HEADER)) return ::testing::AssertionFailure() << "bad header";
    if (std::strcmp(header->GetDeviceType(), "SENSOR") != 0 || std::strcmp(header->GetDeviceName(), "FORCE") != 0)
      return ::testing::AssertionFailure() << "got " << header->GetDeviceType() << " " << header->GetDeviceName();
    igtl::SensorMessage::Pointer sensor = igtl::SensorMessage::New();
    sensor->SetMessageHeader(header);
    sensor->AllocatePack();
    const int body = sensor->GetPackBodySize();
    if (socket_->Receive(sensor->GetPackBodyPointer(), body) != body) return ::testing::AssertionFailure() << "short body";
    if (!(sensor->Unpack(1) & igtl::MessageHeader::UNPACK_BODY)) return ::testing::AssertionFailure() << "bad CRC";
    if (sensor->GetLength() != 3) return ::testing::AssertionFailure() << "length " << sensor->GetLength();
    igtl::Unit::Pointer newton = igtl::Unit::New();
    newton->Append(igtl::Unit::SI_DERIVED_NEWTON, 1);
    if (sensor->GetUnit() != newton->Pack()) return ::testing::AssertionFailure() << "unit is not N";
    for (unsigned i = 0; i < 3; ++i) f[i] = sensor->GetValue(i);
    return ::testing::AssertionSuccess();
  }

  // True when the device closed the connection (reads end of stream).
  bool closed_by_peer() {
    char byte;
    return socket_->Receive(&byte, 1) == 0;
  }

 private:
  igtl::ClientSocket::Pointer socket_;
  bool connected_ = false;
};

// Row-major 4x4: rotation `angle` about a fixed axis, translation p.
void make_matrix(double angle, const Eigen::Vector3d& p, igtl::Matrix4x4& m) {
  const Eigen::Matrix3d r = Eigen::AngleAxisd(angle, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) m[i][j] = i == 3 ? (j == 3 ? 1.0f : 0.0f) : static_cast<float>(j == 3 ? p[i] : r(i, j));
}

::testing::AssertionResult pose_is(const ToolPose& pose, double angle, const Eigen::Vector3d& p) {
  const Eigen::Quaterniond q(Eigen::AngleAxisd(angle, Eigen::Vector3d(1, 2, 3).normalized()));  // w > 0 for |angle| < pi
  const double want_q[4] = {q.w(), q.x(), q.y(), q.z()};
  for (int i = 0; i < 3; ++i)
    if (std::abs(pose.p[i] - p[i]) > 1e-6) return ::testing::AssertionFailure() << "p[" << i << "] " << pose.p[i] << " != " << p[i];
  for (int i = 0; i < 4; ++i)
    if (!(std::abs(pose.q[i] - want_q[i]) <= 1e-6))
      return ::testing::AssertionFailure() << "q[" << i << "] " << pose.q[i] << " != " << want_q[i];
  if (pose.jaw != 0.0) return ::testing::AssertionFailure() << "jaw " << pose.jaw;
  return ::testing::AssertionSuccess();
}

// Polls read() as the haptic loop would, until a fresh reading arrives.
bool read_fresh(IgtlDevice& device, DeviceSample& s) {
  return eventually([&] { return device.read(0.0, s) && s.fresh; });
}

// One transform and its reply; the pose must come through.
void round_trip(IgtlDevice& device, Client& client, double angle, const Eigen::Vector3d& p) {
  igtl::Matrix4x4 m;
  make_matrix(angle, p, m);
  ASSERT_TRUE(client.send_transform(m));
  DeviceSample s;
  ASSERT_TRUE(read_fresh(device, s));
  EXPECT_TRUE(pose_is(s.pose, angle, p));
  Force f;
  ASSERT_TRUE(client.receive_force(f));
}

TEST(IgtlDevice, ThousandTransformsEachGetTheLatestForce) {
  IgtlDevice device(0, 5.0);
  device.start();
  ASSERT_GT(device.port(), 0);
  EXPECT_EQ(device.describe(), "openigtlink (TCP port " + std::to_string(device.port()) + ")");
  DeviceSample s;
  EXPECT_FALSE(device.read(0.0, s));  // nothing connected yet

  Client client(device.port());
  ASSERT_TRUE(client.connected());
  const int n = 1000;
  Force written{0, 0, 0}, before{0, 0, 0}, reply{};
  for (int i = 0; i < n; ++i) {
    const double angle = -3.0 + 6.0 * i / (n - 1);
    const Eigen::Vector3d p(0.25 * i, -0.5 * i, 100.0 + 0.125 * (i % 50));  // exact in the wire's float32
    const Force f{0.001 * i, -1.0 - 0.002 * i, std::sin(0.01 * i)};
    // Odd i: the force is written before the transform goes out, so its reply
    // must carry it. Even i: written after the pose is read, as the loop does,
    // racing the reply, which then carries it or the one before.
    if (i % 2 == 1) {
      before = written;
      written = f;
      device.write_force(0.0, f);
    }
    igtl::Matrix4x4 m;
    make_matrix(angle, p, m);
    ASSERT_TRUE(client.send_transform(m)) << i;
    ASSERT_TRUE(read_fresh(device, s)) << i;
    ASSERT_TRUE(pose_is(s.pose, angle, p)) << i;
    EXPECT_EQ(s.buttons, 0u);
    ASSERT_TRUE(device.read(0.0, s));
    EXPECT_FALSE(s.fresh) << i;  // the same reading, not fresh twice
    if (i % 2 == 0) {
      before = written;
      written = f;
      device.write_force(0.0, f);
    }
    ASSERT_TRUE(client.receive_force(reply)) << i;
    if (i % 2 == 1) ASSERT_EQ(reply, written) << i;
    else ASSERT_TRUE(reply == written || reply == before) << i;
  }
  EXPECT_EQ(reply, written);  // the last reply carries the last force written
  EXPECT_EQ(device.transforms_received(), n);
  EXPECT_TRUE(eventually([&] { return device.forces_sent() == n; }));  // counted after the send returns
  EXPECT_EQ(device.forces_sent(), n);
  EXPECT_EQ(device.connections(), 1);
  EXPECT_EQ(device.rejected_messages(), 0);
  EXPECT_TRUE(device.connected());
}

TEST(IgtlDevice, SurvivesADisconnectAndServesTheNextClient) {
  IgtlDevice device(0, 5.0);
  device.start();
  {
    Client first(device.port());
    ASSERT_TRUE(first.connected());
    for (int i = 0; i < 3; ++i) round_trip(device, first, 0.1 * i, Eigen::Vector3d(i, 0, 0));
  }  // closes
  EXPECT_TRUE(eventually([&] { return !device.connected(); }));
  Client second(device.port());
  ASSERT_TRUE(second.connected());
  for (int i = 0; i < 10; ++i) round_trip(device, second, -0.2 * i, Eigen::Vector3d(0, i, 1));
  EXPECT_EQ(device.connections(), 2);
  EXPECT_TRUE(device.connected());
  EXPECT_EQ(device.transforms_received(), 13);
  EXPECT_TRUE(eventually([&] { return device.forces_sent() == 13; }));
}

TEST(IgtlDevice, ASilentClientMakesWayForANewOne) {
  IgtlDevice device(0, 5.0);
  device.start();
  Client stale(device.port());  // a tracker that went away without closing
  ASSERT_TRUE(stale.connected());
  round_trip(device, stale, 0.3, Eigen::Vector3d(1, 2, 3));
  Client fresh(device.port());
  ASSERT_TRUE(fresh.connected());
  round_trip(device, fresh, -0.3, Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(device.connections(), 2);
  EXPECT_TRUE(stale.closed_by_peer());
}

TEST(IgtlDevice, ANonRotationGivesANanQuaternion) {
  IgtlDevice device(0, 5.0);
  device.start();
  Client client(device.port());
  ASSERT_TRUE(client.connected());
  auto expect_nan_q = [&](const igtl::Matrix4x4& m, const char* what) {
    ASSERT_TRUE(client.send_transform(m)) << what;
    DeviceSample s;
    ASSERT_TRUE(read_fresh(device, s)) << what;
    for (double c : s.pose.q) EXPECT_TRUE(std::isnan(c)) << what;
    EXPECT_EQ(s.pose.p[0], 7.0) << what;  // the translation passes as sent
    Force f;
    EXPECT_TRUE(client.receive_force(f)) << what;  // still answered
  };
  igtl::Matrix4x4 m;
  make_matrix(0.5, Eigen::Vector3d(7, 8, 9), m);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m[i][j] *= 2.0f;
  expect_nan_q(m, "scaled by 2");
  make_matrix(0.5, Eigen::Vector3d(7, 8, 9), m);
  m[1][2] = std::nanf("");
  expect_nan_q(m, "a NaN entry");
  make_matrix(0.5, Eigen::Vector3d(7, 8, 9), m);
  for (int j = 0; j < 3; ++j) m[0][j] = -m[0][j];
  expect_nan_q(m, "a reflection (det -1)");
  round_trip(device, client, 0.5, Eigen::Vector3d(7, 8, 9));  // and a rotation is one again
  EXPECT_EQ(device.rejected_messages(), 0);  // received, the loop's guard rejects them
}

TEST(IgtlDevice, SkipsOtherTypesAndRejectsBadTransforms) {
  IgtlDevice device(0, 5.0);
  device.start();
  Client client(device.port());
  ASSERT_TRUE(client.connected());

  igtl::StringMessage::Pointer text = igtl::StringMessage::New();
  text->SetDeviceName("Note");
  text->SetString(std::string(5000, 'x').c_str());  // longer than the device's skip buffer
  ASSERT_TRUE(client.send(*text));
  igtl::StatusMessage::Pointer status = igtl::StatusMessage::New();
  status->SetDeviceName("Tracker");
  status->SetCode(igtl::StatusMessage::STATUS_OK);
  status->SetStatusString("tracking");
  ASSERT_TRUE(client.send(*status));
  round_trip(device, client, 1.0, Eigen::Vector3d(1, 1, 1));
  EXPECT_EQ(device.rejected_messages(), 0);

  // A flipped body byte: the CRC fails; no pose, no reply, the stream stays in step.
  igtl::Matrix4x4 m;
  make_matrix(0.2, Eigen::Vector3d(3, 3, 3), m);
  igtl::TransformMessage::Pointer bad = igtl::TransformMessage::New();
  bad->SetDeviceName("StylusToTracker");
  bad->SetMatrix(m);
  bad->Pack();
  static_cast<unsigned char*>(bad->GetPackBodyPointer())[5] ^= 0x40;
  ASSERT_TRUE(client.send_raw(bad->GetPackPointer(), bad->GetPackSize()));
  // A TRANSFORM whose header says 40 bytes (a transform is 48): skipped whole.
  bad->Pack();
  unsigned char* body_size = static_cast<unsigned char*>(bad->GetPackPointer()) + 42;  // big-endian uint64
  std::memset(body_size, 0, 8);
  body_size[7] = 40;
  ASSERT_TRUE(client.send_raw(bad->GetPackPointer(), IGTL_HEADER_SIZE + 40));
  round_trip(device, client, -1.0, Eigen::Vector3d(2, 2, 2));
  EXPECT_EQ(device.rejected_messages(), 2);
  EXPECT_EQ(device.transforms_received(), 2);
  EXPECT_TRUE(eventually([&] { return device.forces_sent() == 2; }));
  EXPECT_EQ(device.connections(), 1);  // all on one connection
}

TEST(IgtlDevice, StopsWithinASecondWhileAClientIsSilent) {
  IgtlDevice device(0, 5.0);
  device.start();
  Client client(device.port());
  ASSERT_TRUE(client.connected());
  round_trip(device, client, 0.0, Eigen::Vector3d(0, 0, 0));
  ASSERT_TRUE(device.connected());
  const auto t0 = Clock::now();
  device.stop();
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 1.0);
  EXPECT_FALSE(device.connected());
  EXPECT_TRUE(client.closed_by_peer());
  device.stop();  // idempotent
}

TEST(IgtlDevice, RestartsOnTheSamePortAfterClosingAConnection) {
  // The device closed the connection first (TIME_WAIT on its side) and the
  // port was bound explicitly: a restart must still get it.
  IgtlDevice device(0, 5.0);
  device.start();
  const int port = device.port();
  {
    Client client(port);
    ASSERT_TRUE(client.connected());
    round_trip(device, client, 0.0, Eigen::Vector3d(0, 0, 0));
    device.stop();
  }
  IgtlDevice again(port, 5.0);
  ASSERT_NO_THROW(again.start());
  EXPECT_EQ(again.port(), port);
  Client client(port);
  ASSERT_TRUE(client.connected());
  round_trip(again, client, 0.4, Eigen::Vector3d(1, 0, 0));
  again.stop();
  ASSERT_NO_THROW(again.start());  // the same object, the same port
  EXPECT_EQ(again.port(), port);
}

TEST(IgtlDevice, ClosesEveryDescriptor) {
  // 1.11's CloseSocket() only shuts sockets down; the device closes them.
  auto open_fds = [] {
    const std::filesystem::directory_iterator fds("/proc/self/fd");
    return std::distance(begin(fds), end(fds));
  };
  const long before = open_fds();
  {
    IgtlDevice device(0, 5.0);
    device.start();
    for (int k = 0; k < 3; ++k) {
      Client client(device.port());
      ASSERT_TRUE(client.connected());
      round_trip(device, client, 0.1 * k, Eigen::Vector3d(k, 0, 0));
    }
    device.stop();
  }
  EXPECT_EQ(open_fds(), before);
}

TEST(IgtlDevice, RejectsBadArgumentsAndABusyPort) {
  EXPECT_THROW(IgtlDevice(-1, 5.0), Error);
  EXPECT_THROW(IgtlDevice(65536, 5.0), Error);
  EXPECT_THROW(IgtlDevice(0, 0.0), Error);
  EXPECT_THROW(IgtlDevice(0, -1.0), Error);
  EXPECT_THROW(IgtlDevice(0, std::nan("")), Error);
  EXPECT_THROW(IgtlDevice(0, HUGE_VAL), Error);
  IgtlDevice device(0, 2.5);
  EXPECT_EQ(device.max_force(), 2.5);
  EXPECT_EQ(device.describe(), "openigtlink (TCP port 0)");
  device.start();
  EXPECT_THROW(device.start(), Error);  // running already
  IgtlDevice rival(device.port(), 5.0);
  try {
    rival.start();
    ADD_FAILURE() << "a second device listened on a busy port";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("openigtlink: cannot listen on TCP port " + std::to_string(device.port()) + ": "),
              std::string::npos)
        << e.what();
  }
}

// The device in the haptic loop: a tracker streams 1,000 transforms (mm)
// pushing the tool 2 mm into a rigid floor (a one-row contact model, the
// coupling spring k in series); the tool follows every transform, scaled to
// metres, and the client gets the coupling force k * depth back.
TEST(IgtlDevice, DrivesTheHapticLoopAndGetsItsForces) {
  auto owned = std::make_unique<IgtlDevice>(0, 5.0);
  IgtlDevice& device = *owned;
  HapticSettings hs;
  hs.scale = 0.001;
  hs.damping = 0.0;
  ToolPose start;
  start.p = {0.0, 0.0, 0.005};
  HapticLoop loop(std::move(owned), hs, start);
  device.start();
  HapticContactModel& floor = loop.model_buffer();  // gap = z + lambda / k (a rigid floor at z = 0)
  floor.frame = 0;
  floor.rows = 1;
  floor.D[2] = -1.0;
  floor.Wc[0] = 1.0 / hs.stiffness;
  loop.publish_model();
  Client client(device.port());
  ASSERT_TRUE(client.connected());
  const int n = 1000;
  auto z_mm = [&](int i) { return 5.0 - 7.0 * i / (n - 1); };  // 5 mm above to 2 mm below
  auto expected = [&](int i) { return std::max(0.0, -z_mm(i) * 1e-3) * hs.stiffness; };
  double t = 0.0;
  // Drained after every transform: a loaded machine spins many ticks per
  // transform, which would overflow the records queue over 1,000 of them.
  std::vector<TickRecord> records;
  std::vector<HapticEvent> events;
  for (int i = 0; i < n; ++i) {
    igtl::Matrix4x4 m;
    make_matrix(0.0, Eigen::Vector3d(1.0, 2.0, z_mm(i)), m);
    ASSERT_TRUE(client.send_transform(m));
    ASSERT_TRUE(eventually([&] {
      t += 1e-3;
      loop.tick(t, t);
      const auto& p = loop.device_pose().p;
      return p[0] == 1e-3 && p[1] == 2e-3 && std::abs(p[2] - 1e-3 * static_cast<float>(z_mm(i))) < 1e-12;
    })) << "transform " << i;
    Force f;
    ASSERT_TRUE(client.receive_force(f));
    const double before = i > 0 ? expected(i - 1) : 0.0;  // the reply carries the force of the tick before, or this one
    EXPECT_TRUE(std::abs(f[2] - before) < 1e-4 || std::abs(f[2] - expected(i)) < 1e-4) << i << ": " << f[2];
    loop.drain(records, events);
  }
  EXPECT_EQ(loop.dropped(), 0u);
  EXPECT_TRUE(events.empty()) << event_name(events.front().kind);
  EXPECT_NEAR(records.back().force[2], 2.0, 1e-4) << "k * 2 mm";
  EXPECT_EQ(device.transforms_received(), n);
  loop.stop();
}

}  // namespace
}  // namespace incise
