#include <gtest/gtest.h>

#include "slam_core/io/text_table.h"
#include "slam_core/io/trajectory_io.h"
#include "test_files.h"

namespace ccm {
namespace {

using test::RandomTrajectory;
using test::ScratchDir;
using test::WriteText;

void ExpectSame(const Trajectory& a, const Trajectory& b, double tol) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].stamp_ns, b[i].stamp_ns) << i;
    EXPECT_LT((a[i].world_from_cam.translation() - b[i].world_from_cam.translation()).norm(), tol);
    EXPECT_LT(a[i].world_from_cam.rotation().angularDistance(b[i].world_from_cam.rotation()), tol);
  }
}

TEST(TrajectoryIo, TumRoundTripKeepsNanosecondStamps) {
  ScratchDir dir;
  const Trajectory written = RandomTrajectory(50, 1);
  ASSERT_TRUE(WriteTumTrajectory(dir / "t.txt", written).ok());
  Trajectory read;
  const IoStatus s = ReadTumTrajectory(dir / "t.txt", &read);
  ASSERT_TRUE(s.ok()) << s.message();
  ExpectSame(written, read, 1e-12);
}

TEST(TrajectoryIo, EurocRoundTrip) {
  ScratchDir dir;
  const Trajectory written = RandomTrajectory(50, 2);
  ASSERT_TRUE(WriteEurocTrajectory(dir / "gt.csv", written).ok());
  Trajectory read;
  ASSERT_TRUE(ReadEurocTrajectory(dir / "gt.csv", &read).ok());
  ExpectSame(written, read, 1e-12);
}

TEST(TrajectoryIo, KittiRoundTripWithAndWithoutTimes) {
  ScratchDir dir;
  const Trajectory written = RandomTrajectory(20, 3);
  ASSERT_TRUE(WriteKittiPoses(dir / "poses.txt", written).ok());
  TrajectoryReadOptions options;
  options.format = TrajectoryFormat::kKitti;
  Trajectory read;
  ASSERT_TRUE(ReadTrajectory(dir / "poses.txt", options, &read).ok());
  ASSERT_EQ(read.size(), 20u);
  EXPECT_EQ(read[7].stamp_ns, 7000000000LL);  // index seconds without times.txt
  std::string times;
  for (int i = 0; i < 25; ++i) times += std::to_string(0.1 * i) + "\n";
  WriteText(dir / "times.txt", times);
  options.kitti_times_path = dir / "times.txt";
  ASSERT_TRUE(ReadTrajectory(dir / "poses.txt", options, &read).ok());
  EXPECT_EQ(read[7].stamp_ns, 700000000LL);
  for (size_t i = 0; i < read.size(); ++i) read[i].stamp_ns = written[i].stamp_ns;
  ExpectSame(written, read, 1e-12);
}

TEST(TrajectoryIo, DetectsFormatFromContent) {
  ScratchDir dir;
  const Trajectory t = RandomTrajectory(5, 4);
  WriteTumTrajectory(dir / "a", t);
  WriteEurocTrajectory(dir / "b", t);
  WriteKittiPoses(dir / "c", t);
  TrajectoryFormat f;
  ASSERT_TRUE(DetectTrajectoryFormat(dir / "a", &f).ok());
  EXPECT_EQ(f, TrajectoryFormat::kTum);
  ASSERT_TRUE(DetectTrajectoryFormat(dir / "b", &f).ok());
  EXPECT_EQ(f, TrajectoryFormat::kEuroc);
  ASSERT_TRUE(DetectTrajectoryFormat(dir / "c", &f).ok());
  EXPECT_EQ(f, TrajectoryFormat::kKitti);
  WriteText(dir / "d", "# only a comment\n1 2 3 4 5\n");
  const IoStatus s = DetectTrajectoryFormat(dir / "d", &f);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find(":2:"), std::string::npos) << s.message();
}

TEST(TrajectoryIo, MalformedInputNamesFileAndLine) {
  ScratchDir dir;
  Trajectory t;
  WriteText(dir / "short.txt", "# header\n0.0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 1\n");
  IoStatus s = ReadTumTrajectory(dir / "short.txt", &t);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("short.txt:3: expected 8 fields"), std::string::npos) << s.message();

  WriteText(dir / "nan.txt", "0.0 0 0 x 0 0 0 1\n");
  s = ReadTumTrajectory(dir / "nan.txt", &t);
  EXPECT_NE(s.message().find("nan.txt:1: field 4 is not a number: 'x'"), std::string::npos)
      << s.message();

  WriteText(dir / "quat.txt", "0.0 0 0 0 0 0 0 2\n");
  s = ReadTumTrajectory(dir / "quat.txt", &t);
  EXPECT_NE(s.message().find("quat.txt:1: quaternion norm"), std::string::npos) << s.message();

  WriteText(dir / "gt.csv", "#timestamp\n1.5,0,0,0,1,0,0,0\n");
  s = ReadEurocTrajectory(dir / "gt.csv", &t);
  EXPECT_NE(s.message().find("gt.csv:2: timestamp '1.5'"), std::string::npos) << s.message();

  std::vector<SE3> poses;
  WriteText(dir / "k.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 1 0 0 0 0 1 0\n");
  s = ReadKittiPoses(dir / "k.txt", &poses);
  EXPECT_NE(s.message().find("k.txt:2: rotation is not orthonormal"), std::string::npos)
      << s.message();

  s = ReadTrajectory(dir / "missing.txt", {}, &t);
  EXPECT_NE(s.message().find("no such file"), std::string::npos) << s.message();
}

TEST(TrajectoryIo, SecondsParseToExactNanoseconds) {
  int64_t ns = 0;
  ASSERT_TRUE(io_internal::ParseSecondsToNs("1305031102.175304", &ns));
  EXPECT_EQ(ns, 1305031102175304000LL);
  ASSERT_TRUE(io_internal::ParseSecondsToNs("1.038752e-01", &ns));
  EXPECT_EQ(ns, 103875200LL);
  ASSERT_TRUE(io_internal::ParseSecondsToNs("-0.5", &ns));
  EXPECT_EQ(ns, -500000000LL);
  ASSERT_TRUE(io_internal::ParseSecondsToNs("12.0000000005", &ns));
  EXPECT_EQ(ns, 12000000001LL);
  EXPECT_FALSE(io_internal::ParseSecondsToNs("0x10", &ns));
  EXPECT_FALSE(io_internal::ParseSecondsToNs("nan", &ns));
}

}  // namespace
}  // namespace ccm
