#include "hq/link/link.hpp"
#include "hq/link/test_support.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <string>
#include <utility>

namespace hq::link {
namespace {

using ::testing::HasSubstr;

TEST(Entities, OutOfRangeDomainIdThrowsNamingCallAndDomain) {
  const std::string message = hq::testing::input_error_message([] { Participant p(500); });
  EXPECT_THAT(message, HasSubstr("dds_create_participant(domain 500)"));
  EXPECT_THAT(message, HasSubstr("Bad Parameter"));
}

TEST(Entities, WriterOnDeletedParticipantThrowsNamingCallAndTopic) {
  Participant participant(test::private_domain_id());
  Topic<VelocityCommand> topic(participant);
  // GIVEN a participant deleted behind the wrapper's back (its children go with it)
  ASSERT_GE(dds_delete(participant.handle()), 0);
  // WHEN a writer is created on it THEN the error names the call and the topic
  const std::string message = hq::testing::input_error_message([&] {
    Writer<VelocityCommand> writer(participant, topic, command_qos(LinkConfig{}, End::kWriter));
  });
  EXPECT_THAT(message, HasSubstr("dds_create_writer(hq_velocity_command): "));
}

TEST(Entities, TopicWithInvalidNameThrowsNamingIt) {
  Participant participant(test::private_domain_id());
  const std::string message = hq::testing::input_error_message(
      [&] { Topic<VelocityCommand> topic(participant, "bad name with spaces"); });
  EXPECT_THAT(message, HasSubstr("dds_create_topic(bad name with spaces): "));
}

TEST(Entities, WriteOnDeletedWriterReportsReasonWithoutThrowing) {
  Participant participant(test::private_domain_id());
  Topic<VelocityCommand> topic(participant);
  Writer<VelocityCommand> writer(participant, topic, command_qos(LinkConfig{}, End::kWriter));
  ASSERT_GE(dds_delete(writer.handle()), 0);
  VelocityCommand command{};
  EXPECT_FALSE(writer.write(command));
  EXPECT_STRNE(writer.last_error(), "");
}

TEST(Entities, MovedWriterKeepsWorkingAndSourceIsEmpty) {
  Participant participant(test::private_domain_id());
  Topic<VelocityCommand> topic(participant);
  Reader<VelocityCommand> reader(participant, topic, command_qos(LinkConfig{}, End::kReader));
  Writer<VelocityCommand> first(participant, topic, command_qos(LinkConfig{}, End::kWriter));
  const dds_entity_t handle = first.handle();
  Writer<VelocityCommand> second(std::move(first));
  EXPECT_EQ(second.handle(), handle);
  EXPECT_EQ(first.handle(), 0);  // NOLINT(bugprone-use-after-move): checking the moved-from state
  ASSERT_TRUE(test::wait_for_readers(participant, second, 1));
  VelocityCommand command{};
  command.vehicle_id = 7;
  command.sequence_number = 42;
  ASSERT_TRUE(second.write(command));
  VelocityCommand received{};
  ASSERT_TRUE(test::take_within(participant, reader, received));
  EXPECT_EQ(received.sequence_number, 42u);
}

TEST(Entities, WaitSetReturnsZeroOnTimeoutAndWakesOnGuardCondition) {
  Participant participant(test::private_domain_id());
  WaitSet waitset(participant);
  GuardCondition guard(participant);
  waitset.attach(guard.handle(), 99);
  std::array<dds_attach_t, 2> triggered{};
  EXPECT_EQ(waitset.wait(triggered, DDS_MSECS(1)), 0);
  guard.set(true);
  ASSERT_EQ(waitset.wait(triggered, test::kPatience), 1);
  EXPECT_EQ(triggered[0], 99);
}

TEST(Entities, AttachingDeletedEntityThrowsNamingCall) {
  Participant participant(test::private_domain_id());
  WaitSet waitset(participant);
  GuardCondition guard(participant);
  const dds_entity_t handle = guard.handle();
  ASSERT_GE(dds_delete(handle), 0);
  const std::string message = hq::testing::input_error_message([&] { waitset.attach(handle, 1); });
  EXPECT_THAT(message, HasSubstr("dds_waitset_attach(entity " + std::to_string(handle) + "): "));
}

}  // namespace
}  // namespace hq::link
